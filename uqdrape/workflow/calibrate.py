"""``uqdrape calibrate``: measured fibre angles -> a calibrated ``[uncertainty.zero_angle]``
block (and its figure)."""

from __future__ import annotations

from pathlib import Path

from ..calibration import block_text, calibrate_points, read_points
from ..files import write_text_atomic


def calibrate_fibre_angles(points_csv, out, plot=None, *, family: str = "auto", criterion: str = "aic",
                           level: float = 0.9, fibre1_deg: float = 45.0, command: str = "uqdrape calibrate",
                           posterior: bool = False) -> str:
    """Fit the γ0 field of the points in ``points_csv`` and write the study block ``out``
    (.toml), with the calibration figure if ``plot`` (True: beside the block, or a PNG
    path); the figure first, so a failed one leaves no block; ``posterior``: an emcee
    sample too (its intervals in the comments, sd_dof from it). Returns the summary."""
    out = Path(out)
    if out.suffix.lower() != ".toml":
        raise ValueError(f"--out must name the study block to write, a .toml path; got {str(out)!r}")
    calibration = calibrate_points(read_points(points_csv), fibre1_deg=fibre1_deg, family=family,
                                   criterion=criterion, level=level, posterior=posterior)
    png = None
    if plot:
        from ..calibration.figure import plot_calibration

        png = plot_calibration(calibration, out.with_suffix(".png") if plot is True else Path(plot))
    write_text_atomic(out, block_text(calibration, command))
    fit = calibration.fit
    est = fit.estimates
    sd = est["sd_deg"]
    text = (f"wrote {out}: {fit.family} field (by {fit.criterion.upper()}) of {len(calibration.points)} points, "
            f"mean_deg {est['mean_deg'].value:.4g}, sd_deg {sd.value:.4g} [{sd.lower:.4g}, {sd.upper:.4g}]")
    if fit.family != "iid":
        text += ", length_mm [{:.4g}, {:.4g}]".format(est["length_1_mm"].value, est["length_2_mm"].value)
    return text + f" ({100 * fit.level:g} % intervals in the block's comments)" + (f"\nwrote {png}" if png else "")
