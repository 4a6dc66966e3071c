"""uqdrape: uncertainty quantification for kinematic drape of dry textile preforms.

Units at every interface: lengths mm, forces N, energies J, angles degrees.
"""

__version__ = "0.1.0"
