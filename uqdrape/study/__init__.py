"""Study files: the specification a study file gives (``spec``) and the TOML validator
that reads one (``validate``). ``load_study(path)`` is the way in.

The bottom of the application: reading a study imports nothing that drapes, analyses,
samples an ensemble or reports (``tests/test_layout.py``); what a study needs of the
machine and of its physics is checked by ``uqdrape.workflow.preflight``."""

from .spec import FACTOR_SETTINGS, FIELDS, SENSITIVITY_METHODS, Study, from_dict, identity
from .validate import StudyError, load_study, study_error

__all__ = ["FACTOR_SETTINGS", "FIELDS", "SENSITIVITY_METHODS", "Study", "StudyError", "from_dict", "identity", "load_study", "study_error"]
