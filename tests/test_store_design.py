"""A blank-holder design run into a zarr store's URL (issue 28): its per-design records
and design.nc go under the URL, a second run resumes from them, and its report is read
from there, as a run folder's. test_design's synthetic drape (a known optimum) keeps it
fast; file://, memory:// and moto's S3 on 127.0.0.1 against the same design in a run folder."""

from __future__ import annotations

import json

import fsspec
import numpy as np
import pytest
import xarray as xr

from uqdrape import design
from uqdrape.ensemble import at
from uqdrape.study import load_study
from uqdrape.workflow import run_design, run_report

from test_design import synthetic_drape, write

TEXT = ('variables = "force"\nforce_bounds_N = [0.0, 1000.0]\nobjective = "q95_max_abs_shear"\n'
        'statistic = "estimate"\ntolerance_N = 2.0\nmax_evaluations = 12\n')


def no_drape(*args):
    raise AssertionError("a resumed design drapes nothing: every record is in the store")


@pytest.mark.parametrize("kind", ("file", "memory", "s3"))
def test_design_in_a_store_equals_the_folders_resumes_and_reports(tmp_path, s3, kind):  # noqa: F811
    study = load_study(write(tmp_path, TEXT))
    folder = run_design(study, scheduler="synchronous", progress=False, drape=synthetic_drape)
    url = {"file": f"file://{tmp_path}/store", "memory": f"memory://{tmp_path.name}/design",
           "s3": f"s3://runs/design-{tmp_path.name}"}[kind]
    assert run_design(study, output_dir=url, scheduler="synchronous", progress=False, drape=synthetic_drape) == url
    want, got = xr.load_dataset(folder / design.DESIGN_FILE), at(url).read_dataset(design.DESIGN_FILE)
    for ds in (want, got):
        del ds.attrs["wall_time_s"]
    xr.testing.assert_identical(want, got)
    fs, root = fsspec.core.url_to_fs(url)
    records = sorted(p.rsplit("/", 1)[-1] for p in fs.ls(f"{root}/{design.EVALUATIONS}", detail=False))
    assert records == sorted(p.name for p in (folder / design.EVALUATIONS).iterdir()) and len(records) > 3
    again = run_design(study, output_dir=url, scheduler="synchronous", progress=False, drape=no_drape)
    resumed = at(again).read_dataset(design.DESIGN_FILE)
    np.testing.assert_array_equal(resumed["x"].values, want["x"].values)
    index = run_report(url)
    assert index == f"{url}/report/index.html"
    summary = json.loads(fs.cat_file(f"{root}/report/summary.json"))
    assert summary["figures"] == ["objective.png", "risk_map.png", "convergence.png"]
    assert not fs.exists(f"{root}/run.lock")
