"""A report reads right where there is nothing to show: no node at risk says so (in the
headline and on the map, white for zero probability), and the page describes the run,
not its first chunk."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import write_study
from uqdrape.cli import main as cli
from uqdrape.report.ensemble_figures import RISK_CMAP


@pytest.fixture(scope="module")
def riskless(tmp_path_factory):
    """A small random study over a 50 mm dome whose shear stays far below any locking angle."""
    folder = tmp_path_factory.mktemp("riskless")
    path = write_study(folder, uncertainty={"spacing": {"cv": 0.01}})
    assert cli(["run", str(path), "--scheduler", "synchronous", "-q"]) == 0
    return folder / "tiny" / "report"


def test_no_node_at_risk_is_said_instead_of_naming_an_arbitrary_node(riskless):
    risk = json.loads((riskless / "summary.json").read_text())["max_wrinkle_probability"]
    assert risk["value"] == 0.0
    page = (riskless / "index.html").read_text()
    assert "no node at risk in 6 drapes" in page
    assert "0.000 [" not in page  # no zero probability printed at a node


def test_the_risk_colour_map_is_white_at_zero_and_red_at_one():
    np.testing.assert_array_equal(RISK_CMAP(0.0), (1.0, 1.0, 1.0, 1.0))
    r, g, b, _ = RISK_CMAP(1.0)
    assert r > 0.3 and g < 0.1 and b < 0.1


def test_the_page_describes_the_run_not_its_first_chunk(riskless):
    page = (riskless / "index.html").read_text()
    assert "uqdrape ensemble: study tiny, 6 realisations at 50 N" in page
    assert "realisations 0-1" not in page  # chunk 0's own title
    assert "<th>mould</th><td>hemisphere (radius" in page and "<th>geometry</th>" not in page


def test_the_per_node_statistics_are_a_cf_netcdf_file_on_the_mean_positions(riskless):
    import xarray as xr

    with xr.open_dataset(riskless / "statistics.nc") as st:
        assert st.attrs["Conventions"] == "CF-1.8" and st.attrs["title"] == "uqdrape per-node statistics: tiny"
        for name in ("mean", "sd", "quantile_value", "wrinkle_probability"):
            assert st[name].encoding["coordinates"] == "x y z", name
        assert st["mean"].attrs["units"] == "degree" and st["x"].attrs["units"] == "mm"
        assert int(st["count"].max()) == 6 and float(st["wrinkle_probability"].max()) == 0.0
