"""Tests of uqdrape.report: figures are lossless PNGs whose drawn data are right (shared
colour limits across levels, per-level histogram ranges, force levels in the titles),
each study kind's plan leaves out what does not apply, the HTML page links only files
that exist and states its provenance, summary.json equals the statistics functions, and
the experimental CSV is checked with clear errors."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import matplotlib as mpl
import numpy as np
import pytest
import xarray as xr
from matplotlib.colors import to_hex
from matplotlib.figure import Figure
from matplotlib.image import imread
from PIL import Image

import uqdrape
from uqdrape.drape import drape
from uqdrape.geometry import Hemisphere, NoseCone
from uqdrape.material import load_material
from uqdrape.report import (
    plot_convergence,
    plot_histograms,
    plot_line_statistics,
    plot_lines,
    plot_mean_map,
    plot_net,
    plot_sd_map,
    plot_sensitivity_vs_force,
    plot_sweep,
    plot_wrinkle_map,
    read_experimental,
    write_report,
)
from uqdrape.report.figures import _line_panels, panels, save, suptitle
from uqdrape.report.style import COLUMN_IN, DPI, ROW_IN
from uqdrape.report.html import default_histogram_nodes
from uqdrape.report.plan import PLAN
from uqdrape.schema import by_force
from uqdrape.stats import STUDY_KINDS, convergence, exceedance_probability, node_statistics, samples_needed, study_kind

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
RINGS = 6


@pytest.fixture(scope="module")
def material():
    return load_material("ebxhd936_like")


@pytest.fixture(scope="module")
def ensemble(material):
    """12 energy drapes over a hemisphere with iid zero-energy angles (sd 5 deg)."""
    rng = np.random.default_rng(5)
    R = 12
    return drape(Hemisphere(100.0), 5.0, RINGS, gamma0=rng.normal(0.0, 5.0, (R, 2 * RINGS, 2 * RINGS)),
                 mode="energy", material=material)


@pytest.fixture(scope="module")
def sweep(material):
    """A blank-holder force sweep ensemble: dims (blankholder_force, realization, i, j)."""
    rng = np.random.default_rng(6)
    R, n, forces = 8, 4, [0.0, 300.0]
    parts = [drape(NoseCone(), 5.0, n, gamma0=rng.normal(0.0, 5.0, (R, 2 * n, 2 * n)), mode="energy",
                   material=material, blankholder_force=f).drop_vars("applied_blankholder_force")
             for f in forces]
    force = xr.DataArray(forces, dims="blankholder_force", name="blankholder_force", attrs={"units": "N"})
    return xr.concat(parts, dim=force)


@pytest.fixture(scope="module")
def geodesic():
    """Geodesic drapes with random segment lengths: no material, so no locking angle; some invalid nodes."""
    rng = np.random.default_rng(7)
    R, n = 10, 14
    return drape(Hemisphere(40.0, flange_half_width=50.0), 5.0, n, seg_i=rng.normal(5.0, 0.1, (R, 2 * n, 2 * n + 1)),
                 seg_j=rng.normal(5.0, 0.1, (R, 2 * n + 1, 2 * n)))


@pytest.fixture()
def exp_csv(tmp_path):
    path = tmp_path / "measured.csv"
    path.write_text("distance_mm,shear_deg,quadrant_sign,blankholder_force_N\n"
                    "10,2.5,1,0\n20,6,+1,\n10,-4,-1,300\n30,-15.5,-1,\n")
    return path


@pytest.fixture()
def drawn(monkeypatch):
    """The matplotlib Figures saved during a test, in order (to check what they show)."""
    figures = []
    original = Figure.savefig

    def record(self, *args, **kwargs):
        figures.append(self)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", record)
    return figures


def titles(fig):
    return [ax.get_title() for ax in fig.axes if ax.get_title()]


def png_shape(path, min_bytes=5000):
    """Check a real, non-trivial PNG; return its (rows, cols) in pixels."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert len(data) > min_bytes
    image = imread(path)
    assert image.ndim == 3 and image.shape[2] in (3, 4)
    assert image[..., :3].std() > 0.05  # not a blank canvas
    return image.shape[:2]


# ---------------------------------------------------------------- single drapes


def test_plot_net_node_and_cell_variables(ensemble, tmp_path):
    rows, cols = png_shape(plot_net(ensemble, tmp_path / "net.png"))
    # one panel of 7.0 x 5.6 in, drawn a page column wide (style.COLUMN_IN) at the report's DPI
    height_px, width_px = 5.6 * COLUMN_IN / 7.0 * DPI, COLUMN_IN * DPI
    # the lowest allowed matplotlib (3.8.4) gave 1123 rows where the newest gives 1124: one truncates
    # the canvas's inches x dpi to whole pixels, the other rounds
    assert rows in {int(height_px), round(height_px)} and cols in {int(width_px), round(width_px)}
    png_shape(plot_net(ensemble, tmp_path / "cells.png", var="cell_shear", realization=3, title="cells"))


def test_plot_net_skips_invalid_nodes(geodesic, tmp_path):
    assert geodesic["x"].isel(realization=0).isnull().any()  # the fixture really has invalid nodes
    png_shape(plot_net(geodesic, tmp_path / "net.png"))


def test_plot_net_of_a_sweep_shares_one_colour_scale_and_names_each_level(sweep, tmp_path, drawn):
    plot_net(sweep, tmp_path / "net.png", realization=2)
    fig, = drawn
    *nets, bar = fig.axes
    assert [ax.get_title() for ax in nets] == ["F_BH = 0 N", "F_BH = 300 N"]
    # cell shear = mean of its four corner nodes; the scale is +-max |cell shear| over both levels
    node = sweep["shear"].isel(realization=2).transpose("blankholder_force", "i", "j").values
    cells = (node[:, :-1, :-1] + node[:, 1:, :-1] + node[:, 1:, 1:] + node[:, :-1, 1:]) / 4
    per_level = np.nanmax(abs(cells), axis=(1, 2))
    assert per_level[0] != pytest.approx(per_level[1], rel=0.01)  # a scale per level would differ
    np.testing.assert_allclose(bar.get_ylim(), (-per_level.max(), per_level.max()), rtol=1e-12)


def test_plot_net_errors(ensemble, tmp_path):
    with pytest.raises(ValueError, match="var='nope'"):
        plot_net(ensemble, tmp_path / "a.png", var="nope")
    with pytest.raises(ValueError, match=r"realization must be a position 0..11"):
        plot_net(ensemble, tmp_path / "a.png", realization=12)
    with pytest.raises(ValueError, match="quadrant"):
        plot_net(ensemble.expand_dims(quadrant=2), tmp_path / "a.png")
    with pytest.raises(ValueError, match=r"\.png"):
        plot_net(ensemble, tmp_path / "a.jpg")
    assert not list(tmp_path.iterdir())


def test_figure_titles_fit_their_figure_and_wrap_only_when_they_must():
    head, detail = "ST of node shear on the mean net (x-y plan), nose cone, ebxhd936_like, energy drape", \
        "Sobol' sample, 128 base samples, 896 drapes per level"
    wide = Figure(figsize=(21.6, 4.2))  # room for both on one line
    suptitle(wide, head, detail)
    assert wide._suptitle.get_text() == f"{head}: {detail}"
    narrow = Figure(figsize=(5.8, 2.7))  # 5.8 in at 13 pt: 58 characters a line
    with mpl.rc_context({"figure.titlesize": 13}):
        suptitle(narrow, head, detail)
    lines = narrow._suptitle.get_text().split("\n")
    assert lines[1:] == ["ebxhd936_like, energy drape", detail] and len(lines[0]) <= 58
    assert " ".join(lines) == f"{head} {detail}"  # wrapped at words, nothing lost


def test_save_writes_the_rendered_pixels_losslessly(tmp_path):
    fig, (ax,) = panels(1, size=(3.0, 2.0))
    ax.imshow(np.linspace(0, 1, 256)[None, :], aspect="auto", cmap="viridis")  # a smooth colour bar
    fig.set_dpi(DPI)  # save's
    fig.canvas.draw()
    rendered = np.asarray(fig.canvas.buffer_rgba())
    path = save(fig, tmp_path / "ramp.png")
    with Image.open(path) as im:
        assert im.mode == "RGB"
        np.testing.assert_array_equal(np.asarray(im), rendered[..., :3])
    assert (rendered[..., 3] == 255).all()  # nothing was lost with the alpha channel
    assert len(np.unique(rendered[..., :3].reshape(-1, 3), axis=0)) > 256  # more colours than a palette holds


def test_plot_lines_one_panel_per_force(material, tmp_path):
    one = drape(NoseCone(), 5.0, 8, mode="energy", material=material)
    four = drape(NoseCone(), 5.0, 8, mode="energy", material=material, blankholder_force=[378.0, 0.0, 126.0, 252.0])
    single = png_shape(plot_lines(one, tmp_path / "one.png"))
    grid = png_shape(plot_lines(four, tmp_path / "four.png"))
    # one panel fills a page column, 2 x 2 panels of the same shape the row
    assert (single[1], grid[1]) == (round(COLUMN_IN * DPI), round(ROW_IN * DPI))
    assert abs(grid[0] / grid[1] - single[0] / single[1]) < 1 / single[1]
    groups = _line_panels(by_force(four), 0)
    assert [f for f, _ in groups] == [0.0, 126.0, 252.0, 378.0]
    for force, sub in groups:
        assert sub["applied_blankholder_force"].values.tolist() == [force]


def test_plot_lines_sweep_dim_and_all_realisations(sweep, tmp_path):
    rows, cols = png_shape(plot_lines(sweep, tmp_path / "sweep.png", realization=None))
    assert cols > 1.9 * rows  # two panels side by side
    assert [sub.sizes["realization"] for _, sub in _line_panels(sweep, None)] == [8, 8]


def test_plot_lines_experimental_overlay_changes_the_figure(ensemble, exp_csv, tmp_path):
    plain = imread(plot_lines(ensemble, tmp_path / "plain.png"))
    with_points = imread(plot_lines(ensemble, tmp_path / "points.png", experimental=exp_csv))
    assert plain.shape == with_points.shape and np.abs(plain - with_points).max() > 0.1


# ---------------------------------------------------------------- experimental CSV


def test_read_experimental_values_and_force_filter(exp_csv):
    pts = read_experimental(exp_csv)
    np.testing.assert_array_equal(pts.distance_mm, [10, 20, 10, 30])
    np.testing.assert_array_equal(pts.shear_deg, [2.5, 6, -4, -15.5])
    np.testing.assert_array_equal(pts.quadrant_sign, [1, 1, -1, -1])
    np.testing.assert_array_equal(pts.at_force(300.0).shear_deg, [6, -4, -15.5])  # blank force = every panel


@pytest.mark.parametrize("text, match", [
    ("distance_mm,shear_deg\n1,2\n", r"missing column\(s\) \['quadrant_sign'\]"),
    ("distance_mm,shear_deg,quadrant_sign\n1,abc,1\n", r"row 2: column 'shear_deg': expected a number"),
    ("distance_mm,shear_deg,quadrant_sign\n1,2,1\n3,4,2\n", r"row 3: quadrant_sign = '2'; valid: \+1"),
    ("distance_mm,shear_deg,quadrant_sign\n-1,2,1\n", r"distance_mm = '-1' must be >= 0"),
    ("distance_mm,shear_deg,quadrant_sign\n", "no data rows"),
    ("distance_mm,shear_deg,quadrant_sign\n1,nan,1\n", "expected a finite number"),
])
def test_malformed_experimental_csv(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        read_experimental(path)


def test_missing_experimental_csv(tmp_path, ensemble):
    with pytest.raises(ValueError, match="does not exist"):
        plot_lines(ensemble, tmp_path / "x.png", experimental=tmp_path / "none.csv")
    with pytest.raises(ValueError, match="experimental must be None, a CSV path"):
        plot_lines(ensemble, tmp_path / "x.png", experimental=[1, 2])


# ---------------------------------------------------------------- ensemble figures


def test_ensemble_figures_draw_their_statistics(ensemble, exp_csv, tmp_path, drawn):
    st = node_statistics(ensemble)
    png_shape(plot_mean_map(ensemble, tmp_path / "mean.png"))
    png_shape(plot_sd_map(ensemble, tmp_path / "sd.png"))
    png_shape(plot_wrinkle_map(ensemble, tmp_path / "risk.png", threshold_deg=8.0))
    png_shape(plot_line_statistics(ensemble, tmp_path / "ls.png", experimental=exp_csv))
    png_shape(plot_histograms(ensemble, tmp_path / "hist.png", [(3, 3), (-3, 3)]))
    png_shape(plot_convergence(ensemble, tmp_path / "conv.png", (2, 2)))
    mean, sd, risk, lines, hist, conv = drawn
    vmax = float(abs(st["mean"]).max())
    assert mean.axes[0].collections[0].get_clim() == pytest.approx((-vmax, vmax), rel=1e-12)
    assert sd.axes[0].collections[0].get_clim() == pytest.approx((0.0, float(st["sd"].max())), rel=1e-12)
    ex = exceedance_probability(ensemble, 8.0)
    top = ex.isel(ex["probability"].argmax(...))
    assert risk.axes[0].collections[0].get_clim() == (0.0, 1.0)
    assert risk.axes[0].texts[0].get_text() == (f"max P = {float(top['probability']):.2f} "
                                                f"[{float(top['probability_lower']):.2f}, "
                                                f"{float(top['probability_upper']):.2f}]")
    assert any("experiment" in t.get_text() for t in lines.axes[0].get_legend().get_texts())
    for ax, node in zip(hist.axes, [(3, 3), (-3, 3)]):
        values = ensemble["shear"].sel(i=node[0], j=node[1]).values
        np.testing.assert_allclose(ax.patches[0].get_data().edges, np.histogram_bin_edges(values, 20), rtol=1e-12)
        assert ax.get_title() == f"node {node}, {'+' if node[0] * node[1] > 0 else '−'} quadrant, F_BH = 0 N"
    ax_h = conv.axes[1]
    final_sd = float(convergence(ensemble, (2, 2))["running_sd"][-1])
    marks = [line.get_xdata()[0] for line in ax_h.get_lines() if line.get_linestyle() == ":"]
    assert marks == [samples_needed(final_sd, 1.0, 0.95)]


def test_sweep_figures_share_scales_name_levels_and_bin_each_level(sweep, tmp_path, drawn):
    for path in (plot_mean_map(sweep, tmp_path / "mean.png"), plot_line_statistics(sweep, tmp_path / "ls.png")):
        rows, cols = png_shape(path)
        assert cols > 1.7 * rows
    png_shape(plot_sweep(sweep, tmp_path / "sweep.png"))
    png_shape(plot_histograms(sweep, tmp_path / "hist.png", [(2, 2), (-2, 2)]))
    png_shape(plot_convergence(sweep, tmp_path / "conv.png"))
    mean, lines, _, hist, _ = drawn
    levels = ("F_BH = 0 N", "F_BH = 300 N")
    mean_panels = [ax for ax in mean.axes if ax.get_title()]
    assert [ax.get_title() for ax in mean_panels] == list(levels)
    vmax = float(abs(node_statistics(sweep)["mean"]).max())
    assert [ax.collections[0].get_clim() for ax in mean_panels] == [pytest.approx((-vmax, vmax))] * 2
    assert titles(lines) == list(levels)
    assert lines.axes[0].get_ylim() == lines.axes[1].get_ylim()
    # one panel per node and level, each on bins over its own level's values
    assert titles(hist) == [f"node {n}, {q} quadrant, {f}" for n, q in (((2, 2), "+"), ((-2, 2), "−")) for f in levels]
    ranges = []
    for ax, (node, force) in zip(hist.axes, [(n, f) for n in ((2, 2), (-2, 2)) for f in (0.0, 300.0)]):
        values = sweep["shear"].sel(blankholder_force=force, i=node[0], j=node[1]).values
        np.testing.assert_allclose(ax.patches[0].get_data().edges, np.histogram_bin_edges(values, 20), rtol=1e-12)
        ranges.append((values.min(), values.max()))
    assert ranges[0][1] < ranges[1][0] or ranges[1][1] < ranges[0][0]  # the levels do not overlap: a shared
    # range would put each level's values into a few of the bins


def test_ensemble_figure_errors(ensemble, geodesic, tmp_path):
    with pytest.raises(ValueError, match="plot_sweep needs two or more 'blankholder_force' levels"):
        plot_sweep(ensemble, tmp_path / "s.png")
    with pytest.raises(ValueError, match="no 'locking_angle_deg'|threshold_deg"):
        plot_wrinkle_map(geodesic.drop_attrs(), tmp_path / "w.png")
    with pytest.raises(ValueError, match="node i=9"):
        plot_histograms(ensemble, tmp_path / "h.png", [(9, 9)])
    with pytest.raises(ValueError, match="target_deg"):
        plot_convergence(ensemble, tmp_path / "c.png", target_deg=0.0)


# ---------------------------------------------------------------- write_report


def linked_files(index):
    return re.findall(r'(?:src|href)="([^"]+)"', index.read_text())


def test_write_report_links_and_summary_numbers(ensemble, exp_csv, tmp_path):
    # without the drape's `locked` flag the risk falls back to the locking-angle attribute:
    # a threshold the ensemble straddles, so the risk is not all 0
    ds = ensemble.drop_vars("locked")
    ds.attrs["locking_angle_deg"] = 8.0
    study = '[study]\nname = "x<y>"\n'
    index = write_report(ds, tmp_path / "rep", title="Test <report>", study_text=study,
                         experimental_csv=exp_csv, summary={"wall time (s)": 3.5})
    out = index.parent
    links = linked_files(index)
    assert links and all((out / name).is_file() for name in links)
    summary = json.loads((out / "summary.json").read_text())
    expected = {"net.png", "lines.png", "mean_shear.png", "sd_shear.png", "wrinkle_risk.png",
                "line_statistics.png", "histograms.png", "convergence.png"}
    assert set(summary["figures"]) == expected
    assert expected | {"summary.json"} == set(links)
    for name in expected:
        png_shape(out / name)
    html_text = index.read_text()
    assert "Test &lt;report&gt;" in html_text and 'name = &quot;x&lt;y&gt;&quot;' in html_text

    st = node_statistics(ds)
    sd = st["sd"]
    i, j = summary["max_sd_deg"]["node"]
    assert summary["max_sd_deg"]["value"] == float(sd.max()) == float(sd.sel(i=i, j=j))
    mean_abs = abs(st["mean"])
    assert summary["max_abs_mean_shear_deg"]["value"] == float(mean_abs.max())
    assert summary["valid_fraction"] == float(st["count"].sum()) / (12 * (2 * RINGS + 1) ** 2) == 1.0
    ex = exceedance_probability(ds, 8.0)
    wr = summary["max_wrinkle_probability"]
    at = ex.sel(i=wr["node"][0], j=wr["node"][1])
    assert wr["value"] == float(ex["probability"].max()) == float(at["probability"])
    assert 0 < wr["value"] and wr["lower"] == float(at["probability_lower"]) < wr["value"] <= wr["upper"]
    assert wr["upper"] == float(at["probability_upper"]) and wr["measure"] == "P(|shear| > 8°)"
    assert summary["samples_needed"]["value"] == samples_needed(float(sd.max()), 1.0, 0.95)
    assert summary["extra"] == {"wall time (s)": 3.5}
    assert f"{summary['samples_needed']['value']}</td>" in html_text


def test_wrinkle_risk_comes_from_the_locked_flag_when_the_drape_has_it(ensemble, tmp_path, unrasterised):
    ds = ensemble.copy()
    ds["locked"] = (abs(ds["shear"]) > 8.0).astype(float).where(ds["shear"].notnull())
    index = write_report(ds, tmp_path, title="locked")
    summary = json.loads((tmp_path / "summary.json").read_text())
    ex = exceedance_probability(ds, 0.5, var="locked")
    wr = summary["max_wrinkle_probability"]
    assert wr["measure"] == "P(next to a locked cell)"
    assert 0 < wr["value"] == float(ex["probability"].max())
    assert "wrinkle_risk.png" in summary["figures"] and "P(next to a locked cell)" in index.read_text()


def test_write_report_sweep(sweep, tmp_path, unrasterised):
    index = write_report(sweep, tmp_path, title="sweep")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert {"net.png", "sweep.png", "histograms.png"} <= set(summary["figures"])
    assert all((tmp_path / name).is_file() for name in linked_files(index))
    assert summary["blankholder_force_levels_N"] == [0.0, 300.0] and summary["realizations"] == 8
    site = summary["max_sd_deg"]
    sd = node_statistics(sweep)["sd"]
    assert site["value"] == float(sd.max())
    assert site["value"] == float(sd.sel(blankholder_force=site["blankholder_force_N"], i=site["node"][0],
                                         j=site["node"][1]))


def test_write_report_without_locking_angle(geodesic, tmp_path, unrasterised):
    index = write_report(geodesic, tmp_path, title="geodesic")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["max_wrinkle_probability"] is None
    assert "wrinkle_risk.png" not in summary["figures"] and not (tmp_path / "wrinkle_risk.png").exists()
    assert all((tmp_path / name).is_file() for name in linked_files(index))
    valid = geodesic["shear"].notnull()
    assert summary["valid_fraction"] == pytest.approx(float(valid.mean())) and summary["valid_fraction"] < 1.0


def test_write_report_bad_input_writes_nothing(ensemble, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("distance,shear\n1,2\n")
    out = tmp_path / "rep"
    with pytest.raises(ValueError, match="missing column"):
        write_report(ensemble, out, title="t", experimental_csv=bad)
    with pytest.raises(ValueError, match="title must be a non-empty string"):
        write_report(ensemble, out, title=" ")
    with pytest.raises(ValueError, match=r"summary\['x'\]"):
        write_report(ensemble, out, title="t", summary={"x": [1, 2]})
    with pytest.raises(ValueError, match=r"summary\['x'\]"):  # a (value, how) pair's how is a string
        write_report(ensemble, out, title="t", summary={"x": ("1 %", 2)})
    assert not out.exists()


def _numbers(record, prefix=""):
    """The leaves of a summary record as {path: value}."""
    if isinstance(record, dict):
        return {k: v for key, sub in record.items() for k, v in _numbers(sub, f"{prefix}/{key}").items()}
    if isinstance(record, list):
        return {k: v for n, sub in enumerate(record) for k, v in _numbers(sub, f"{prefix}/{n}").items()}
    return {prefix: record}


def test_a_small_lazy_ensemble_is_read_once_and_reports_the_same(ensemble, tmp_path, unrasterised, monkeypatch):
    """A dask-backed ensemble of at most LOAD_BYTES is computed in one pass before the
    statistics; above it every statistic computes lazily. Both reports hold the same numbers
    (to the order of summation) and the same figures."""
    from dask.callbacks import Callback

    from uqdrape.report import html

    lazy = ensemble.chunk({"realization": 4})
    passes = []

    class Count(Callback):
        def _start(self, dsk):
            passes.append(1)

    with Count():
        write_report(lazy, tmp_path / "loaded", title="t")
    assert len(passes) == 1
    monkeypatch.setattr(html, "LOAD_BYTES", 0)
    passes.clear()
    with Count():
        write_report(lazy, tmp_path / "lazy", title="t")
    assert len(passes) > 10
    loaded, lazy_ = (_numbers(json.loads((tmp_path / d / "summary.json").read_text())) for d in ("loaded", "lazy"))
    assert loaded.keys() == lazy_.keys()
    for key, value in loaded.items():
        if isinstance(value, float) and "provenance" not in key:
            assert value == pytest.approx(lazy_[key], rel=1e-12, abs=1e-12), key
        elif "provenance" not in key:
            assert value == lazy_[key], key


def test_default_histogram_nodes_follow_the_thesis(ensemble):
    ds = by_force(ensemble)
    assert default_histogram_nodes(ds, node_statistics(ds)) == [(6, 6), (-6, 6)]


# ---------------------------------------------------------------- the plan of each study kind


def _record(ds, out, **kwargs):
    index = write_report(ds, out, title="t", **kwargs)
    return json.loads((out / "summary.json").read_text()), index.read_text()


def _study_json(**uncertainty):
    return json.dumps({"uncertainty": uncertainty})


def test_study_kind_rules(ensemble, sweep):
    skewed = ensemble.assign(skew=("realization", np.linspace(0.0, 55.0, 12)))
    assert study_kind(ensemble) == "random sample"
    assert study_kind(sweep.isel(realization=[0])) == "deterministic"
    assert study_kind(ensemble.assign_attrs(sample_method="sobol")) == "sensitivity sample"
    assert study_kind(skewed) == "swept factor"  # no study record: one varying scalar factor
    uniform = _study_json(skew={"dist": "uniform", "bounds": [0, 55]})
    assert study_kind(skewed.assign_attrs(study_json=uniform)) == "swept factor"
    normal = _study_json(skew={"dist": "normal", "mean": 0, "sd": 3})
    assert study_kind(skewed.assign_attrs(study_json=normal)) == "random sample"
    field = _study_json(skew={"dist": "uniform", "bounds": [0, 55]}, zero_angle={"sd_deg": 5})
    assert study_kind(skewed.assign_attrs(study_json=field)) == "random sample"


def test_each_kind_s_report_leaves_out_what_does_not_apply(ensemble, sweep, tmp_path, unrasterised):
    assert not bool(ensemble["locked"].any())  # nothing locks in the 12 hemisphere drapes
    random, page = _record(ensemble, tmp_path / "random")
    assert random["figures"] == ["net.png", "lines.png", "mean_shear.png", "sd_shear.png", "line_statistics.png",
                                 "histograms.png", "convergence.png"]
    # no all-zero wrinkle map: a sentence instead, on the page and in the JSON; Wilson upper limit
    # of 0 in 12 at 95 %: z^2 / (12 + z^2) = 3.8415 / 15.8415 = 0.2425
    assert random["notes"] == ["No wrinkle-risk map: no node sits next to a locked cell in any of the 12 "
                               "realisations (the 95% upper limit of the risk is 0.242 or less at every node)."]
    assert random["notes"][0] in page and random["samples_needed"] is not None

    # one drape per level: no histogram, convergence, sd or risk (and no interval on a 1-drape "probability")
    det, page = _record(sweep.isel(realization=[0]), tmp_path / "det")
    assert det["kind"] == "deterministic" and det["notes"] == []
    assert det["figures"] == ["net.png", "lines.png", "sweep.png", "mean_shear.png"]
    assert det["max_sd_deg"] is None and det["max_wrinkle_probability"] is None and det["samples_needed"] is None
    assert "N needed" not in page and "wrinkle risk" not in page and "max |shear| (deg)" in page

    # a uniform sweep over one factor: shown against the factor, no Normal fit, no N needed
    skewed = ensemble.assign(skew=("realization", np.linspace(0.0, 55.0, 12), {"units": "degree"}))
    swept, page = _record(skewed.assign_attrs(study_json=_study_json(skew={"dist": "uniform", "bounds": [0, 55]})),
                          tmp_path / "swept")
    assert swept["figures"] == ["net.png", "lines.png", "vs_skew.png"]
    assert swept["max_sd_deg"] is None and swept["samples_needed"] is None and "N needed" not in page

    # the rows of a sensitivity sample: descriptive maps, no interval, convergence or histogram
    rows, page = _record(ensemble.assign_attrs(sample_method="sobol"), tmp_path / "sensitivity")
    assert rows["figures"] == ["net.png", "lines.png", "mean_shear.png", "sd_shear.png"]
    assert rows["max_sd_deg"]["value"] == random["max_sd_deg"]["value"] and rows["samples_needed"] is None
    for name in ("histograms.png", "convergence.png", "wrinkle_risk.png"):
        assert not (tmp_path / "sensitivity" / name).exists()
    assert {kind for spec in PLAN for kind in spec.kinds} == set(STUDY_KINDS)


def test_every_page_states_its_provenance_and_the_study_once(ensemble, tmp_path, unrasterised):
    study = '[study]\nname = "plate"\n'
    record, page = _record(ensemble.assign_attrs(study_toml=study), tmp_path, study_text=study, wall_time_s=12.34)
    prov = record["provenance"]
    commit = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=Path(uqdrape.__file__).parent,
                            capture_output=True, text=True, check=True).stdout.strip()
    assert prov["git_commit"] == commit and prov["uqdrape_version"] == "0.1.0" and prov["wall_time_s"] == 12.34
    assert re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d UTC", prov["date"])
    assert f"Report of {prov['date']}, uqdrape 0.1.0, git commit\n{commit}; wall time of the run: 12.3 s" in page
    assert page.count("name = &quot;plate&quot;") == 1


def _indices(forces=(0.0,)):
    """Sobol' indices of two factors for two QoIs per force level: ST = S1 + 0.1."""
    s1 = np.array([[0.6, 0.1], [0.2, 0.5]])[..., None] * np.linspace(1.0, 0.5, len(forces))  # factor x qoi x force
    dims, coords = ("factor", "qoi", "blankholder_force"), {"factor": ["friction", "zero_angle"],
                                                            "qoi": ["asymmetry", "blankholder_energy"],
                                                            "blankholder_force": list(forces)}
    conf = np.full(s1.shape, 0.05)
    return xr.Dataset({"S1": (dims, s1), "S1_conf": (dims, conf), "ST": (dims, s1 + 0.1), "ST_conf": (dims, conf),
                       "output_constant": (dims[1:], np.zeros(s1.shape[1:], bool))}, coords=coords,
                      attrs={"method": "sobol", "base_samples": 8, "n_evaluations": 48, "conf_level": 0.95})


def test_sensitivity_legend_tells_st_solid_from_s1_dashed(tmp_path, drawn):
    png_shape(plot_sensitivity_vs_force(_indices([0.0, 300.0]), tmp_path / "vs.png"))
    fig, = drawn
    legend = {t.get_text(): h for t, h in zip(fig.legends[0].get_texts(), fig.legends[0].legend_handles)}
    assert legend["total-order ST"].get_linestyle() == "-" and legend["first-order S1"].get_linestyle() == "--"
    friction = legend["friction"].get_color()
    assert to_hex(friction) == "#1f77b4" and to_hex(legend["zero_angle"].get_color()) == "#ff7f0e"
    # the friction/asymmetry panel: ST solid at 0.7 -> 0.4, S1 dashed at 0.6 -> 0.3
    lines = {line.get_linestyle(): line.get_ydata() for line in fig.axes[0].get_lines()
             if to_hex(line.get_color()) == "#1f77b4"}
    np.testing.assert_allclose(lines["-"], [0.7, 0.4], rtol=1e-12)
    np.testing.assert_allclose(lines["--"], [0.6, 0.3], rtol=1e-12)


def test_sensitivity_page_starts_with_the_indices_and_their_largest_st(ensemble, tmp_path, unrasterised):
    record, page = _record(ensemble.assign_attrs(sample_method="sobol"), tmp_path, sensitivity=_indices())
    assert record["sensitivity"]["largest_ST"] == [{"blankholder_force_N": 0.0, "factor": "friction",
                                                    "qoi": "asymmetry", "ST": 0.7, "ST_conf": 0.05}]
    assert ("largest total-order Sobol&#x27; index ST, F_BH = 0 N</th><td class=\"num\">friction 0.70 ± 0.05</td>"
            "<td>of asymmetry, the largest") in page
    assert page.index("<h2>Sensitivity</h2>") < page.index("<h2>Figures</h2>")
    assert record["figures"][0] == "sensitivity_bars.png"


def test_a_level_where_nothing_exceeds_gets_a_note_instead_of_a_marker(sweep, tmp_path, drawn):
    top = abs(sweep["shear"]).max(["realization", "i", "j"])
    threshold = float(top.sel(blankholder_force=300.0))  # P = 0 at 300 N: |shear| > its own maximum never holds
    assert float(top.sel(blankholder_force=0.0)) > threshold
    plot_wrinkle_map(sweep, tmp_path / "w.png", threshold_deg=threshold)
    fig, = drawn
    at_0, at_300 = [ax for ax in fig.axes if ax.get_title()]
    assert [t.get_text()[:8] for t in at_0.texts] == ["max P = "]
    assert [t.get_text().split("\n")[0] for t in at_300.texts] == ["no node at risk:"] and not at_300.lines
