"""Study files: the specification a study file gives (``spec``) and the TOML validator
that reads one (``validate``). ``load_study(path)`` is the way in."""

from .spec import FACTOR_SETTINGS, FIELDS, SENSITIVITY_METHODS, Study, from_dict
from .validate import StudyError, load_study

__all__ = ["FACTOR_SETTINGS", "FIELDS", "SENSITIVITY_METHODS", "Study", "StudyError", "from_dict", "load_study"]
