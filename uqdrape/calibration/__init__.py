"""uqdrape.calibration: from fibre-angle measurements to a study's variability model.

A CSV of local fibre angles measured on a flat sample (:mod:`.points`) is mapped to the
model's zero-energy shear angle γ0 along the fibre axes (:mod:`.mapping`, where the
mapping is decided), a Gaussian field is fitted to it by restricted maximum likelihood
for each correlation family of ``uqdrape.stochastic.fields`` (:mod:`.likelihood`), the
family chosen by AIC or BIC and every parameter given a profile-likelihood interval
(:mod:`.fit`), and the result written as the study block ``[uncertainty.zero_angle]``
(:mod:`.block`) with a figure (:mod:`.figure`). :mod:`.synthetic` draws measurement sets
from known fields to check a fit.

With emcee (optional extra ``calibrate``) :mod:`.posterior` samples the parameters'
posterior; the block's ``sd_dof`` and ``length_log_sd`` (a hierarchical ensemble drawing
each realisation's sd and correlation lengths, ``uqdrape.ensemble.inputs``) are then
matched to the posterior's intervals instead of the profile's, and ``length_log_sd`` is
left out when a length is unidentified.

:mod:`.image` reads fibre angles off an image of the fabric (scikit-image's structure
tensor, optional extra ``calibrate``) as points for the same fit (``uqdrape calibrate
IMAGE --mm-per-px``).

:func:`.block.unidentified` names the parameters the points do not identify (an open
profile interval, or a posterior piling against the prior's bound).

Measured drapes -> study parameters: :mod:`.emulator` (a GP per ensemble statistic over a
Latin-hypercube training points, scikit-learn), :mod:`.drapes` (the parts' likelihood, the
two-round design of training points, its posterior by emcee, the posterior-predictive
bands) and :mod:`.parameters` (the calibrated study keys and the study at their medians);
the drapes themselves are run by ``uqdrape.workflow.calibrate``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from .block import block_text, study_block
from .fit import CRITERIA, Estimate, FieldFit, fit_field
from .likelihood import FAMILIES
from .mapping import fibre_coordinates, zero_angle_deg
from .points import AnglePoints, PointsError, check_point_count, check_spread, read_points
from .synthetic import synthetic_set

__all__ = ["CRITERIA", "FAMILIES", "AnglePoints", "Estimate", "FieldFit", "PointsCalibration", "PointsError",
           "block_text", "calibrate_points", "fit_field", "read_points", "study_block", "synthetic_set"]


@dataclass
class PointsCalibration:
    """A calibration from measured points: the points, their γ0 (deg) and fibre
    coordinates a, b (mm), the nominal fibre-1 angle (deg from x) and the field fit."""

    points: AnglePoints
    gamma0_deg: np.ndarray
    a_mm: np.ndarray
    b_mm: np.ndarray
    fibre1_deg: float
    fit: FieldFit
    posterior: object = None


def calibrate_points(points: AnglePoints, *, fibre1_deg: float = 45.0, family: str = "auto",
                     criterion: str = "aic", level: float = 0.9, posterior: bool = False) -> PointsCalibration:
    """Fit the γ0 field of measured ``points`` (see the package docstring); ``posterior``:
    also sample the chosen family's posterior (:mod:`.posterior`, needs emcee)."""
    if not -360.0 <= fibre1_deg <= 360.0:
        raise ParameterError("fibre1_deg", f"fibre1_deg must be a finite angle from -360 to 360 deg, got "
                             f"{fibre1_deg!r}")
    check_point_count(len(points), points.source, "thin them, or for an image give a larger window_px (samples "
                                                  "lie two windows apart)")
    check_spread(points)
    gamma0 = zero_angle_deg(points, fibre1_deg)
    a, b = fibre_coordinates(points.x_mm, points.y_mm, fibre1_deg)
    fit = fit_field(a, b, gamma0, points.sd_deg, family=family, criterion=criterion, level=level)
    sample = None
    if posterior:
        from .posterior import posterior_sample

        sample = posterior_sample(fit)
    return PointsCalibration(points, gamma0, a, b, fibre1_deg, fit, sample)
