"""Fibre angles from an image (uqdrape.calibration.image): stripes bent by a known smooth
angle field, clean and photo-like (blur, noise), read back by the structure tensor and
calibrated as measured points."""

from __future__ import annotations

import time

import numpy as np
import pytest
import scipy.ndimage

from uqdrape.calibration import calibrate_points
from uqdrape.calibration.image import image_points, orientation_field

pytest.importorskip("skimage")

#: tows every 16 px (vertically) along y = x + A sin(2 pi x / P) + c: the angle field
#: atan(1 + A 2 pi / P cos(2 pi x / P)), 34.4 to 52.7 deg
PERIOD_PX, A_PX, P_PX = 16.0, 20.0, 400.0


def _stripes(n=1000):
    x = np.arange(n, dtype=float)[None, :]
    y = -np.arange(n, dtype=float)[:, None]
    image = 0.5 + 0.5 * np.cos(2 * np.pi * (y - x - A_PX * np.sin(2 * np.pi * x / P_PX)) / PERIOD_PX)
    true = np.degrees(np.arctan(1 + A_PX * 2 * np.pi / P_PX * np.cos(2 * np.pi * x / P_PX))) * np.ones_like(y)
    return image, true


def _rms(theta, true, border=40):
    e = (theta - true)[border:-border, border:-border]
    e = 90.0 - np.mod(90.0 - e, 180.0)
    return float(np.sqrt(np.mean(e ** 2)))


def test_stripes_bent_by_a_known_field_come_back_within_stated_errors():
    """1 megapixel, window 8 px: clean rms 0.11 deg (asserted < 0.2), blurred (1.5 px) with
    noise of sd 0.3 (the stripes' amplitude 0.5 after blur ~ 0.2) rms 0.51 deg with a 2 px
    inner scale (asserted < 0.8), each in well under a second (measured 0.2 s)."""
    image, true = _stripes()
    clock = time.perf_counter()
    theta, coherence = orientation_field(image, window_px=8.0)
    seconds = time.perf_counter() - clock
    assert _rms(theta, true) < 0.2 and np.median(coherence) > 0.9
    assert seconds < 5.0
    photo = scipy.ndimage.gaussian_filter(image, 1.5) + np.random.default_rng(0).normal(0.0, 0.3, image.shape)
    assert _rms(orientation_field(photo, window_px=8.0, derivative_px=2.0)[0], true) < 0.8
    # a smaller window and no inner scale let the noise in (measured: 0.78 deg at 1 px inner scale, 2.0 at 1 px and window 4)
    assert _rms(orientation_field(photo, window_px=4.0)[0], true) > _rms(
        orientation_field(photo, window_px=8.0, derivative_px=2.0)[0], true)


def test_image_points_calibrate_to_the_known_mean_and_scatter():
    """The sampled angles, read as fibre set 1 at 45 deg, give the field's mean deviation
    and its sd (of the sampled true angles) to 0.2 deg."""
    image, true = _stripes(600)
    points = image_points(image, 0.1, window_px=8.0, source="stripes.png")
    rows = np.rint(-points.y_mm / 0.1).astype(int)
    cols = np.rint(points.x_mm / 0.1).astype(int)
    expected = true[rows, cols] - 45.0
    cal = calibrate_points(points, family="iid")
    assert len(points) > 400
    assert cal.fit.estimates["mean_deg"].value == pytest.approx(expected.mean(), abs=0.2)
    assert cal.fit.estimates["sd_deg"].value == pytest.approx(expected.std(ddof=1), abs=0.2)


def test_bad_image_input_is_refused():
    with pytest.raises(ValueError, match="2-D grey levels"):
        orientation_field(np.zeros((5, 5, 3)))
    with pytest.raises(ValueError, match="mm_per_px"):
        image_points(np.zeros((40, 40)), 0.0)
    with pytest.raises(ValueError, match="no sample of the image has a dominant fibre direction"):
        image_points(np.ones((60, 60)), 0.1)


def test_calibrate_command_reads_an_image(tmp_path, capsys):
    from PIL import Image

    from conftest import assert_one_line_error
    from uqdrape.cli import main

    image, true = _stripes(400)
    png = tmp_path / "tows.png"
    Image.fromarray(np.uint8(np.rint(255 * image))).save(png)
    out = tmp_path / "z.toml"
    assert main(["calibrate", str(png), "--mm-per-px", "0.1", "--family", "iid", "--out", str(out), "-q"]) == 0
    said = capsys.readouterr().out
    assert "iid field" in said and "from tows.png" in out.read_text(encoding="utf-8")
    assert main(["calibrate", str(png), "--out", str(out), "-q"]) != 0
    assert_one_line_error(capsys.readouterr().err, file=png, valid=("--mm-per-px",))
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not an image")
    assert main(["calibrate", str(bad), "--mm-per-px", "0.1", "--out", str(out), "-q"]) != 0
    assert_one_line_error(capsys.readouterr().err, file=bad, valid=(".png",))
