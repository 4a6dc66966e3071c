"""Fibre angles measured from an image of the fabric: the structure tensor.

An image of one fibre set's tows (grey levels, rows top to bottom) is turned into a
local orientation field by the structure tensor of scikit-image (optional extra
``calibrate``): J = G_w * (∇I ∇Iᵀ), the gradients by Sobel-like derivatives of the
image smoothed at ``window_px`` (skimage's ``sigma``, the Gaussian window's sd in
pixels). The gradient's dominant direction is the eigenvector of J's largest eigenvalue,
θ_g = ½ atan2(2 J_xy, J_xx − J_yy) in plan axes (x = column, y = up = −row), and the
tows run across it: θ = θ_g + 90°, wrapped into (−90°, 90°]. The coherence
(λ1 − λ2) / (λ1 + λ2) in [0, 1] says how clearly one direction dominates.

The field is sampled every ``step_px`` pixels (at least the window, so neighbouring
samples are nearly independent readings) into :class:`.points.AnglePoints`, positions
in mm by ``mm_per_px``, which :func:`uqdrape.calibration.calibrate_points` fits as any
measured points. The angular resolution is not the pixel's: a window averages the tows
it covers, so a field varying faster than the window is smoothed (stated by the round
trip in the tests: stripes bent by a known field).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..files import check_input_file
from .points import AnglePoints, PointsError, read_points
from .posterior import extra


def orientation_field(image, window_px: float = 4.0, derivative_px: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(θ, coherence) per pixel of a 2-D grey image: the tows' plan direction θ (deg
    anticlockwise from x, in (−90, 90]) and the structure tensor's coherence;
    ``derivative_px`` > 0 smooths the image first (a Gaussian of that sd, pixels: the
    inner scale, against pixel noise)."""
    image = np.asarray(image, dtype=float)
    if image.ndim != 2 or min(image.shape) < 3:
        raise ValueError(f"the image must be 2-D grey levels of at least 3 x 3 pixels, got shape {image.shape}")
    if not 0 < window_px <= min(image.shape) / 4:  # the samples keep 2 windows off each border
        raise ParameterError("window_px", f"window_px must be > 0 and at most a quarter of the image's smaller "
                             f"side, {min(image.shape) / 4:g} px here, got {window_px!r}")
    if derivative_px > 0:
        import scipy.ndimage

        image = scipy.ndimage.gaussian_filter(image, derivative_px)
    feature = extra("skimage.feature", "an orientation field from an image needs scikit-image")
    a_rr, a_rc, a_cc = feature.structure_tensor(image, sigma=window_px, mode="reflect", order="rc")
    jxx, jyy, jxy = a_cc, a_rr, -a_rc  # x = column, y = -row
    theta = 0.5 * np.degrees(np.arctan2(2.0 * jxy, jxx - jyy)) + 90.0
    theta = 90.0 - np.mod(90.0 - theta, 180.0)
    root = np.hypot(jxx - jyy, 2.0 * jxy)
    total = jxx + jyy
    # a flat patch's tensor is round-off, not a direction: its coherence is 0
    flat = total <= 1e-10 * max(float(np.ptp(image)), np.finfo(float).tiny) ** 2
    coherence = np.divide(root, total, out=np.zeros_like(total), where=~flat)
    return theta, coherence


#: Image file suffixes ``uqdrape calibrate`` reads as an image (anything else: a points CSV).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
#: Most pixels of an image read: the structure tensor holds about ten float arrays of the
#: image's size (16 Mpx: about 1.3 GB); a 4096 x 4096 picture resolves any tow pattern.
MAX_IMAGE_PIXELS = 4096 * 4096
#: Largest image file read, bytes.
MAX_IMAGE_BYTES = 256 * 2**20


def read_image(path) -> np.ndarray:
    """The grey levels (0-1) of the image file ``path``; an unreadable one, or one of more
    than MAX_IMAGE_PIXELS (checked before its pixels are decoded), raises PointsError
    naming it."""
    from PIL import Image, UnidentifiedImageError

    check_input_file(path, "image", MAX_IMAGE_BYTES, error=PointsError)
    try:
        with Image.open(path) as im:
            if im.width * im.height > MAX_IMAGE_PIXELS:
                raise PointsError(f"{path}: the image is {im.width} x {im.height} px, more than the "
                                  f"{MAX_IMAGE_PIXELS / 2**20:g} Mpx read (4096 x 4096); scale it down or crop it",
                                  str(path))
            return np.asarray(im.convert("L"), dtype=float) / 255.0
    except (UnidentifiedImageError, OSError, Image.DecompressionBombError) as err:
        raise PointsError(f"{path}: not a readable image ({type(err).__name__}); valid: "
                          f"{', '.join(IMAGE_SUFFIXES)} files of grey or colour pixels", str(path)) from None


def image_points(image, mm_per_px: float, *, window_px: float = 4.0, derivative_px: float = 0.0,
                 step_px: int | None = None,
                 fibre_set: int = 1, min_coherence: float = 0.2, source: str = "image") -> AnglePoints:
    """Fibre-angle points of one fibre set read off ``image`` every ``step_px`` pixels
    (default: 2 windows), dropping a border of 2 windows and samples of coherence below
    ``min_coherence`` (no dominant direction). Positions: x = column, y = −row, in mm."""
    if not mm_per_px > 0:
        raise ValueError(f"mm_per_px (the image's scale) must be > 0, got {mm_per_px!r}")
    theta, coherence = orientation_field(image, window_px, derivative_px)
    step = int(step_px) if step_px is not None else max(1, int(round(2 * window_px)))
    border = int(np.ceil(2 * window_px))
    rows = np.arange(border, theta.shape[0] - border, step)
    cols = np.arange(border, theta.shape[1] - border, step)
    r, c = (g.ravel() for g in np.meshgrid(rows, cols, indexing="ij"))
    keep = coherence[r, c] >= min_coherence
    r, c = r[keep], c[keep]
    if r.size == 0:
        raise ValueError(f"no sample of the image has a dominant fibre direction (coherence >= {min_coherence:g}); "
                         "a larger window_px averages more tows")
    n = r.size
    return AnglePoints(c * mm_per_px, -r * mm_per_px, theta[r, c], np.full(n, fibre_set), np.zeros(n),
                       np.arange(1, n + 1), source)


def measured_points(path, mm_per_px: float | None, *, window_px: float = 8.0, fibre_set: int = 1) -> AnglePoints:
    """The fibre-angle points of the file ``path``: an image (a suffix of IMAGE_SUFFIXES)
    read as tows of ``fibre_set`` at scale ``mm_per_px`` (mm per pixel) through the
    structure tensor (window ``window_px``, px), any other file a points CSV
    (``points.read_points``; no ``mm_per_px`` then)."""
    path = Path(path)
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        if mm_per_px is not None:
            raise ParameterError("mm_per_px", f"mm_per_px is the scale of an image ({', '.join(IMAGE_SUFFIXES)}); "
                                 f"{path} is read as a points CSV")
        return read_points(path)
    if mm_per_px is None:
        raise ParameterError("mm_per_px", f"{path} is an image: give its scale, mm_per_px (mm per pixel, > 0)")
    return image_points(read_image(path), mm_per_px, window_px=window_px, fibre_set=fibre_set, source=str(path))
