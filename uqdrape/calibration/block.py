"""The calibration as a study block: ``[uncertainty.zero_angle]`` a study uses as is.

The fit is recorded in comment lines above the table, not in a table of its own: a
study file refuses tables it does not know (``uqdrape.study.validate``), and comments
go wherever the block is pasted. They name the source file, the mapping, every family's
criterion, each estimate with its interval and the measurement error left out of the
field. The table holds only what a study reads: ``mean_deg``, ``sd_deg``,
``correlation`` and, for a correlated family, ``length_mm = [L1, L2]`` (mm along fibre 1
and fibre 2), each rounded to 4 significant digits, and ``sd_dof``: the sd's estimation
uncertainty for a hierarchical ensemble (:func:`sd_dof`), unless its interval is open,
and ``length_log_sd``: the lengths' (:func:`length_log_sd`), unless a length is unidentified.
"""

from __future__ import annotations

import math
from datetime import date
from pathlib import Path

import scipy.optimize
import scipy.stats

from .._version import __version__
from ..files import toml_text

#: Significant digits of the values written to the block.
DIGITS = 4


def _round(value: float) -> float:
    return float(f"{value:.{DIGITS}g}")


def _interval(estimate) -> str:
    lower = ("<= " if estimate.lower_open else "") + f"{estimate.lower:.4g}"
    upper = (">= " if estimate.upper_open else "") + f"{estimate.upper:.4g}"
    return f"[{lower}, {upper}]"


def _posterior_ends(calibration) -> dict:
    """The prior bounds each sampled parameter's posterior piles against (name -> bounds;
    :meth:`.posterior.Posterior.at_bounds`), only the parameters that do."""
    if calibration.posterior is None:
        return {}
    from .posterior import prior_box

    ends = {name: calibration.posterior.at_bounds(name, lo, hi, log=True)
            for name, (lo, hi) in prior_box(calibration.fit).items()}
    return {name: e for name, e in ends.items() if e}


def _posterior_bounded(calibration) -> bool:
    """Whether the posterior's intervals are the data's, not the prior box's."""
    return calibration.posterior is not None and not _posterior_ends(calibration)


def unidentified(calibration) -> list[str]:
    """A sentence per parameter the measured points do not identify: its profile-likelihood
    interval is open at the search bound, or its posterior piles against the prior's bound."""
    fit = calibration.fit
    out = [f"{name} is not identified by the data: its profile-likelihood interval {_interval(est)} is open "
           "(the likelihood stays within the cut up to the search bound)"
           for name, est in fit.estimates.items() if est.lower_open or est.upper_open]
    for name, ends in _posterior_ends(calibration).items():
        lo, hi = calibration.posterior.interval(name, fit.level)
        out.append(f"{name} is not identified by the data: its posterior reaches the prior bound "
                   f"{' and '.join(f'{b:.4g}' for b in ends)} ({100 * fit.level:g} % interval [{lo:.4g}, {hi:.4g}] "
                   "is the prior's, not the measurements'); more points over a larger sample would bound it")
    return out


def _matched_interval(calibration, name: str = "sd_deg"):
    """A parameter's estimate with the interval sd_dof or length_log_sd is matched to: the
    posterior's if sampled and bounded by the data (:func:`unidentified`), else the profile's."""
    est = calibration.fit.estimates[name]
    if not _posterior_bounded(calibration):
        return est
    lower, upper = calibration.posterior.interval(name, calibration.fit.level)
    return type(est)(est.value, lower, upper)


LENGTHS = ("length_1_mm", "length_2_mm")


def length_log_sd(calibration) -> float | None:
    """The sd s of ln L for a hierarchical run's lengths L exp(s z) (``[uncertainty.zero_angle]
    length_log_sd``, one z for both): the log-normal whose equal-tailed ``level`` interval is
    as wide as the wider of the two lengths' intervals, ln(upper / lower) / (2 z_(1+level)/2).
    None for iid, and when a length is not identified (:func:`unidentified`: its profile
    interval is open or its posterior reaches the prior's bound)."""
    fit = calibration.fit
    if fit.family == "iid" or any(name in _posterior_ends(calibration) for name in LENGTHS):
        return None
    ests = [_matched_interval(calibration, name) for name in LENGTHS]
    if any(e.lower_open or e.upper_open or not 0 < e.lower < e.upper for e in ests):
        return None
    quantile = scipy.stats.norm.ppf(0.5 + fit.level / 2)
    return max(math.log(e.upper / e.lower) for e in ests) / (2 * quantile)


def sd_dof(estimate, level: float) -> float | None:
    """The degrees of freedom m whose scaled-inverse-χ² sd, σ̂ √(m / χ²_m), has an
    equal-tailed ``level`` interval as wide (in log σ) as ``estimate``'s; None if an end
    is open. For iid points it is n − 1 (the interval is the chi-square one), so a run
    drawing sd_r = σ̂ √(m / χ²_m) per realisation (``[uncertainty.zero_angle] sd_dof``)
    samples the sd's posterior under the reference prior; for a correlated field it is an
    effective m matched to the profile-likelihood interval."""
    if estimate.lower_open or estimate.upper_open or not 0 < estimate.lower < estimate.upper:
        return None
    alpha = 1.0 - level
    target = math.log(estimate.upper / estimate.lower)

    def width(log_m):
        m = math.exp(log_m)
        return 0.5 * math.log(scipy.stats.chi2.ppf(1 - alpha / 2, m) / scipy.stats.chi2.ppf(alpha / 2, m)) - target

    return float(math.exp(scipy.optimize.brentq(width, math.log(0.05), math.log(1e7), xtol=1e-10)))


def study_block(calibration) -> dict:
    """The ``{"uncertainty": {"zero_angle": ...}}`` table of a :class:`PointsCalibration`."""
    fit = calibration.fit
    est = fit.estimates
    table = {"mean_deg": _round(est["mean_deg"].value), "sd_deg": _round(est["sd_deg"].value),
             "correlation": fit.family}
    if fit.family != "iid":
        table["length_mm"] = [_round(est["length_1_mm"].value), _round(est["length_2_mm"].value)]
    m = sd_dof(_matched_interval(calibration), fit.level)
    if m is not None:
        table["sd_dof"] = _round(m)
    s = length_log_sd(calibration)
    if s is not None:
        table["length_log_sd"] = _round(s)
    return {"uncertainty": {"zero_angle": table}}


def block_text(calibration, command: str = "uqdrape calibrate") -> str:
    """The study block as TOML text, the fit in its leading comments."""
    fit = calibration.fit
    points = calibration.points
    sets = {k: int((points.fibre_set == k).sum()) for k in (1, 2)}
    crit = fit.criterion.upper()
    lines = [
        f"[uncertainty.zero_angle] calibrated by `{command}` (uqdrape {__version__}, {date.today().isoformat()})",
        (f"from {Path(points.source).name}: {len(points)} points (fibre set 1: {sets[1]}, set 2: {sets[2]}), "
         f"fibre 1 nominally at {calibration.fibre1_deg:g} deg from x"),
        ("gamma0 = the measured fibre's deviation from nominal, that set rotating against the other "
         "(uqdrape.calibration.mapping); the mean offset reads as the stitch's rest shear"),
        f"family by {crit} of the restricted likelihood (least is kept):",
        *[(f"  {name:20s} {crit} {getattr(f, fit.criterion):10.2f}  log-likelihood {f.loglik:10.2f}"
           f"{'  <- kept' if name == fit.family else ''}") for name, f in fit.fits.items()],
        f"estimates and {100 * fit.level:g} % profile-likelihood intervals (uqdrape.calibration.fit):",
    ]
    for name, estimate in fit.estimates.items():
        if name == "nugget_deg":
            lines.append(f"  {name:12s} {estimate.value:8.4g}  (measurement error beyond the file's sd_deg; "
                         "not part of the study's field)")
        else:
            lines.append(f"  {name:12s} {estimate.value:8.4g}  {_interval(estimate)}")
    post = calibration.posterior
    if post is not None:
        lines.append(f"posterior (emcee, {len(post.samples['sd_deg'])} draws, acceptance {post.acceptance:.2f}, "
                     f"{post.seconds:.1f} s), {100 * fit.level:g} % equal-tailed intervals (uqdrape.calibration.posterior):")
        lines += [f"  {name:12s} [{lo:.4g}, {hi:.4g}]  autocorrelation {post.autocorrelation[name]:.0f} steps"
                  for name in post.samples for lo, hi in [post.interval(name, fit.level)]]
    m = sd_dof(_matched_interval(calibration), fit.level)
    source = "posterior" if _posterior_bounded(calibration) else "profile"
    lines += [f"WARNING: {u}" for u in unidentified(calibration)]
    lines.append(f"sd_dof = {m:.4g}: the sd's {source} interval as a scaled-inverse-chi-square one"
                 + (" (not the posterior's: it reaches its prior bound)" if post is not None and source == "profile"
                    else "") + "; a run draws each "
                 "realisation's sd from it (delete sd_dof for a fixed sd)"
                 if m is not None else "no sd_dof: the sd's interval is open, the data do not bound it")
    if fit.family != "iid":
        s = length_log_sd(calibration)
        lines.append(f"length_log_sd = {s:.4g}: the wider length's {source} interval as a log-normal one about "
                     "its estimate (the median); a run draws each realisation's lengths length_mm exp(s z), one z "
                     "for both (delete length_log_sd for fixed lengths)" if s is not None else
                     "no length_log_sd: a correlation length is not identified by the data (see the warning), "
                     "so the lengths stay fixed at their estimates")
    if points.sd_deg.any():
        lines.append(f"per-point measurement sd from the file: {points.sd_deg.min():.3g} to "
                     f"{points.sd_deg.max():.3g} deg (left out of sd_deg)")
    return toml_text(study_block(calibration), "\n".join(lines))
