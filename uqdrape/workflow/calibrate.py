"""``uqdrape calibrate``: measured fibre angles -> a calibrated ``[uncertainty.zero_angle]``
block (and its figure)."""

from __future__ import annotations

from pathlib import Path

from ..calibration import block_text, calibrate_points, read_points
from ..files import write_text_atomic


def _image_points(path: Path, mm_per_px, window_px: float, fibre_set: int):
    """The points of an image file, or None for a CSV."""
    from ..calibration.image import IMAGE_SUFFIXES, image_points, read_image

    if path.suffix.lower() not in IMAGE_SUFFIXES:
        if mm_per_px is not None:
            raise ValueError(f"--mm-per-px is the scale of an image ({', '.join(IMAGE_SUFFIXES)}); "
                             f"{path} is read as a points CSV")
        return None
    if mm_per_px is None:
        raise ValueError(f"{path} is an image: give its scale, --mm-per-px (mm per pixel, > 0)")
    return image_points(read_image(path), mm_per_px, window_px=window_px, fibre_set=fibre_set, source=str(path))


def calibrate_fibre_angles(points_csv, out, plot=None, *, family: str = "auto", criterion: str = "aic",
                           level: float = 0.9, fibre1_deg: float = 45.0, command: str = "uqdrape calibrate",
                           posterior: bool = False, mm_per_px: float | None = None, window_px: float = 8.0,
                           fibre_set: int = 1) -> str:
    """Fit the γ0 field of the points in ``points_csv`` and write the study block ``out``
    (.toml), with the calibration figure if ``plot`` (True: beside the block, or a PNG
    path); the figure first, so a failed one leaves no block; ``posterior``: an emcee
    sample too (its intervals in the comments, sd_dof from it). An image (a suffix of
    calibration.image.IMAGE_SUFFIXES) is read as tows of ``fibre_set`` at scale
    ``mm_per_px`` through the structure tensor (window ``window_px``). Returns the summary."""
    out = Path(out)
    if out.suffix.lower() != ".toml":
        raise ValueError(f"--out must name the study block to write, a .toml path; got {str(out)!r}")
    points = _image_points(Path(points_csv), mm_per_px, window_px, fibre_set)
    calibration = calibrate_points(points if points is not None else read_points(points_csv), fibre1_deg=fibre1_deg, family=family,
                                   criterion=criterion, level=level, posterior=posterior)
    png = None
    if plot:
        from ..report.calibration_figure import plot_calibration

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
