"""Reports worth printing: every figure is drawn at print resolution with type of at least
9 pt as the page shows it, vector copies on request hold text, and moulds are named in
words. The page's widths are read from its own CSS, the type sizes from the figures."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

import pytest
import xarray as xr
from matplotlib.figure import Figure
from matplotlib.text import Text
from PIL import Image

from conftest import assert_one_line_error, write_study
from uqdrape.cli import main as cli
from uqdrape.geometry import build
from uqdrape.report import write_design_report
from uqdrape.report.style import DPI, MIN_PT, WINDOW_PX
from uqdrape.study import from_dict
from uqdrape.workflow import run_report

CSS_PX_PER_IN = 96  # CSS 2.1
ROOT = Path(__file__).resolve().parent.parent
PAN = ROOT / "studies" / "meshes" / "pan.stl"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A random study (figures of one panel fill a column, of two the row), run without its report."""
    folder = tmp_path_factory.mktemp("print")
    path = write_study(folder, uncertainty={"spacing": {"cv": 0.02}})
    assert cli(["run", str(path), "--scheduler", "synchronous", "-q", "--no-report"]) == 0
    return folder / "tiny"


def drawn_report(write):
    """``write()`` -> index.html, its figures recorded as drawn: (index, [(figure width in,
    [text sizes pt], [texts])] in page order)."""
    saved = []
    real = Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        real(self, fname, *args, **kwargs)  # draws: the tick labels exist now
        if kwargs.get("format") == "png":
            texts = [t for t in self.findobj(Text) if t.get_visible() and t.get_text().strip()]
            saved.append((self.get_figwidth(), [t.get_fontsize() for t in texts], [t.get_text() for t in texts]))

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Figure, "savefig", savefig)
        index = write()
    return index, saved


@pytest.fixture(scope="module")
def drawn(run):
    """The run's report, with SVG and PDF copies, its figures recorded as drawn."""
    return drawn_report(lambda: run_report(run, run / "report", formats=("svg", "pdf")))


def _slots(page: str) -> tuple[float, float]:
    """(row, column) widths (CSS px) of the page's figure grid in a WINDOW_PX window, from its CSS."""
    body = float(re.search(r"body \{[^}]*max-width: (\d+)px", page).group(1))
    padding = float(re.search(r"body \{[^}]*padding: 0 (\d+)px", page).group(1))
    gap = float(re.search(r"\.figures \{[^}]*gap: (\d+)px", page).group(1))
    assert "grid-template-columns: repeat(2, minmax(0, 1fr))" in page and "figure img { width: 100%" in page
    row = min(WINDOW_PX, body) - 2 * padding
    return row, (row - gap) / 2


def assert_print_rule(index, saved) -> list[str]:
    """Every figure of the page ``index`` has >= 200 px per displayed inch and no text under
    9 pt as the page shows it (its width from the page's CSS, its type sizes as drawn);
    returns the figures' classes ("wide" or "")."""
    page = index.read_text()
    row, column = _slots(page)
    figures = re.findall(r'<figure( class="wide")?><a href="([^"]+\.png)">', page)
    assert len(figures) == len(saved)
    for (wide, name), (width_in, sizes, texts) in zip(figures, saved):
        shown_in = (row if wide else column) / CSS_PX_PER_IN  # the figure's width on the page
        with Image.open(index.parent / name) as png:
            assert png.width / shown_in >= 200, name  # pixels per displayed inch
            assert png.width == round(width_in * DPI), name
        scale = shown_in / width_in
        assert 0.99 < scale < 1.01, name  # drawn at the size it is shown: its points are the page's
        smallest = min(sizes)
        assert smallest * scale >= MIN_PT >= 9, (name, smallest, texts[sizes.index(smallest)])
    return [wide for wide, _ in figures]


def test_every_figure_has_print_resolution_and_9_pt_type_as_the_page_shows_it(drawn):
    wide = assert_print_rule(*drawn)
    assert len(wide) >= 7 and any(wide) and not all(wide)  # column and row figures both checked


def test_a_design_page_keeps_the_same_rule(tmp_path):
    """The double dome's sector design (its design.nc, kept as test data): its polar bars on fixed axes too."""
    ds = xr.load_dataset(ROOT / "tests" / "data" / "design-doubledome-sectors.nc")
    surface = from_dict(json.loads(ds.attrs["study_json"]), ROOT).geometry.build_mould()
    index, saved = drawn_report(lambda: write_design_report(ds, tmp_path, surface=surface))
    assert len(assert_print_rule(index, saved)) == 4  # objective, sectors, risk maps, convergence


def test_vector_copies_exist_parse_and_hold_text(drawn):
    index, saved = drawn
    page = index.read_text()
    names = re.findall(r'<img src="([^"]+)\.png"', page)
    assert len(names) == len(saved)
    for name, (_, _, texts) in zip(names, saved):
        assert f'<a href="{name}.svg">SVG</a><a href="{name}.pdf">PDF</a>' in page
        svg = ET.parse(index.parent / f"{name}.svg").getroot()
        text = [" ".join(t.itertext()) for t in svg.iter("{http://www.w3.org/2000/svg}text")]
        longest = max((line for t in texts for line in t.split("\n")), key=len)
        assert any(longest in t for t in text), (name, longest)  # as text, not glyph outlines
        pdf = (index.parent / f"{name}.pdf").read_bytes()
        assert pdf.startswith(b"%PDF-") and b"/FontFile2" in pdf  # an embedded TrueType font
        streams = [zlib.decompress(s) for s in re.findall(rb"stream\r?\n(.*?)\r?\nendstream", pdf, re.S)
                   if s[:1] == b"x"]
        assert any(b"Tj" in s or b"TJ" in s for s in streams), name  # text shown as text


def test_a_bad_format_is_one_line_and_writes_nothing(run, capsys):
    out = run / "bad-report"
    assert cli(["report", str(run), "--out", str(out), "--format", "svg", "png"]) == 2
    assert_one_line_error(capsys.readouterr().err, valid=["--format", "'png'", "svg, pdf"])
    assert not out.exists()


def test_moulds_are_named_in_words_on_the_page_and_in_titles(drawn):
    index, saved = drawn
    assert "<th>mould</th><td>hemisphere (radius 50 mm, flange half width 100 mm)</td>" in index.read_text()
    titles = [t for _, _, texts in saved for t in texts if "hemisphere (radius 50 mm" in t]
    assert titles and not any("hemisphere(" in t or "radius=" in t for _, _, texts in saved for t in texts)
    assert build("nose_cone").describe() == ("nose cone (base radius 225 mm, half angle 35°, tip radius 50 mm, "
                                             "flange half width 450 mm)")
    assert build("mesh", path=PAN).describe() == "mesh pan.stl (mm, press +z)"
    assert build("mesh", path=PAN, units="in", press_direction="-1,0,0",
                 edge_blend_mm=0.5).describe() == "mesh pan.stl (in, press -x, edge blend 0.5 mm)"


@pytest.mark.slow  # a Sobol' run and its whole page: 13 s at load 5
def test_a_sensitivity_page_keeps_the_same_rule(tmp_path):
    """Sobol' indices of two factors at two blank-holder levels: bars, indices against force and index maps."""
    path = write_study(tmp_path, study={"chunk_size": 128}, process={"blankholder_force_N": [0.0, 50.0]},
                       uncertainty={"spacing": {"cv": 0.02}, "orientation": {"dist": "uniform", "bounds": [-2.0, 2.0]}},
                       sensitivity={"method": "sobol", "base_samples": 64})
    assert cli(["run", str(path), "--scheduler", "synchronous", "-q", "--no-report"]) == 0
    index, saved = drawn_report(lambda: run_report(tmp_path / "tiny"))
    names = re.findall(r'<img src="([^"]+)\.png"', index.read_text())
    assert names[:4] == ["sensitivity_vs_force", "sensitivity_bars", "sensitivity_map_S1", "sensitivity_map_ST"]
    assert_print_rule(index, saved)
