"""uqdrape: uncertainty quantification for kinematic drape of dry textile preforms.

Units at every interface: lengths mm, forces N, energies J, angles degrees.
"""

#: The one place the version is written: pyproject.toml reads it (setuptools dynamic version).
__version__ = "0.1.0"
