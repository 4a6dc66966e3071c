"""The reference gallery (``tools/gallery.py``) and the pieces it relies on: ring
statistics, the scalar-vs-factor figure, the README it writes, and each entry's study.
The gallery's output is not kept in git: ``python tools/gallery.py`` writes it."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from PIL import Image

from uqdrape.drape import drape
from uqdrape.geometry import build
from uqdrape.report import plot_scalar_vs_factor, write_report
from uqdrape.schema import by_force
from uqdrape.stats import inner_outer_sd, ring_sd, varying_factors
from uqdrape.study import load_study

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))
import gallery  # noqa: E402  (tools/gallery.py, a script of the checkout)


def _ring_dataset(n: int = 6) -> xr.Dataset:
    """shear = z_r * k at ring k, z = (-1, 0, 1): per-node sd (ddof 1) equals the ring number."""
    idx = np.arange(-n, n + 1)
    ring = np.maximum(np.abs(idx)[:, None], np.abs(idx)[None, :])
    z = np.array([-1.0, 0.0, 1.0])
    shear = z[:, None, None] * ring[None]
    return xr.Dataset({"shear": (("realization", "i", "j"), shear, {"units": "degree"})},
                      coords={"realization": [0, 1, 2], "i": idx, "j": idx})


def test_ring_sd_averages_the_node_sd_of_each_ring():
    per_ring = ring_sd(_ring_dataset(6))
    assert per_ring.dims == ("ring",)
    np.testing.assert_allclose(per_ring["ring"].values, np.arange(1, 7))
    np.testing.assert_allclose(per_ring.values, np.arange(1, 7), rtol=1e-12)


def test_inner_outer_sd_leaves_out_the_boundary_ring():
    inner, outer = inner_outer_sd(_ring_dataset(6), band=2)
    assert inner == pytest.approx(1.5)  # rings 1, 2
    assert outer == pytest.approx(4.5)  # rings 4, 5 (not 6)
    with pytest.raises(ValueError, match="band=3 needs a net of at least 7 rings, got 6"):
        inner_outer_sd(_ring_dataset(6), band=3)


@pytest.fixture(scope="module")
def skewed():
    """Geodesic hemisphere drapes at four skews (deg), 200 N, friction 0.3 (thesis Fig 5.6 set-up)."""
    skew = np.array([40.0, 0.0, 20.0, 55.0])
    return drape(build("hemisphere", radius=100.0), 5.0, 8, skew=skew, blankholder_force=200.0, friction=0.3)


def test_varying_factors_names_only_the_factors_that_vary(skewed):
    assert varying_factors(skewed) == ["skew"]
    assert varying_factors(skewed.isel(realization=[0])) == []


def test_plot_scalar_vs_factor_writes_a_png_and_checks_its_input(skewed, tmp_path):
    path = plot_scalar_vs_factor(skewed, tmp_path / "vs_skew.png", "skew")
    with Image.open(path) as im:
        assert im.size[0] > 800 and im.size[1] > 300
    with pytest.raises(ValueError, match="factor='orientation' is not a variable along 'realization'; valid: .*skew"):
        plot_scalar_vs_factor(skewed.drop_vars("orientation", errors="ignore"), tmp_path / "x.png", "orientation")
    sweep = by_force(skewed).reindex(blankholder_force=[200.0, 300.0])  # two levels
    with pytest.raises(ValueError, match="takes one blank-holder level"):
        plot_scalar_vs_factor(sweep, tmp_path / "x.png", "skew")


def test_report_of_a_varying_skew_has_the_factor_figure(skewed, tmp_path, unrasterised):
    write_report(skewed, tmp_path, title="skew")
    record = json.loads((tmp_path / "summary.json").read_text())
    assert "vs_skew.png" in record["figures"]
    assert (tmp_path / "vs_skew.png").is_file()


def test_readme_lists_the_entries_present(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    entry = gallery.GALLERY[0]
    folder = gallery.GALLERY_DIR / entry.name
    folder.mkdir(parents=True)
    (folder / "headline.json").write_text(json.dumps(
        {"study": entry.study.as_posix(), "thesis_figure": entry.figure, "thesis": entry.thesis,
         "headline": {"E_BH (J)": 2.44}}))
    text = gallery.write_readme().read_text()
    assert f"[![{entry.name}]({entry.name}/{entry.picture})]({entry.name}/index.html)" in text
    assert "E_BH (J): 2.44" in text and entry.figure in text
    assert gallery.GALLERY[1].name not in text  # absent entries are left out
    assert "python tools/gallery.py" in text


def test_only_rejects_an_unknown_entry(capsys):
    with pytest.raises(SystemExit) as stop:
        gallery.main(["--only", "no-such-study"])
    assert stop.value.code == 2
    assert "invalid choice: 'no-such-study'" in capsys.readouterr().err


@pytest.mark.parametrize("entry", gallery.GALLERY, ids=lambda e: e.name)
def test_each_entry_has_its_study(entry):
    study = load_study(ROOT / entry.study)
    assert study.name == entry.name
    assert str(study.output_dir) == f"results/{entry.name}"
