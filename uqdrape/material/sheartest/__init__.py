"""From raw shear tests to material cards (thesis ch. 3, §3.3-3.4).

- ``picture_frame``: PF kinematics (Eq 3.1-3.5) and normalisation (Eq 3.16);
- ``bias_extension``: BE kinematics (Eq 3.17-3.19) and the energy normalisation
  (§3.4.4.1), exact and by the thesis's iterative and polynomial routes;
- ``fit``: the monotone fit of noisy force data and the valid-range rule;
- ``reader``: the rig file (TOML) and the specimens' test CSVs;
- ``card``: specimens -> a mean card with its per-angle scatter.
"""

from .bias_extension import BiasExtension
from .card import CardFit, SpecimenFit, fit_card, fit_specimen
from .picture_frame import PictureFrame
from .reader import RigFile, ShearTestError, read_rig, read_test_csv

__all__ = ["BiasExtension", "CardFit", "PictureFrame", "RigFile", "ShearTestError", "SpecimenFit", "fit_card",
           "fit_specimen", "read_rig", "read_test_csv"]
