"""The shipped cluster script (studies/cluster/run_on_cluster.py) on a local dask cluster:
the same command line a SLURM or PBS run takes, with ``--cluster local`` (dask-jobqueue
and a batch system are not available here). Its ensemble equals the synchronous run's."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
import xarray as xr

from uqdrape.ensemble import open_ensemble, run_ensemble
from uqdrape.study import load_study

from conftest import write_study

SCRIPT = Path(__file__).resolve().parents[1] / "studies" / "cluster" / "run_on_cluster.py"


@pytest.mark.slow  # a LocalCluster of 2 processes and 24 drapes: ~15 s on the loaded 2-core machine
def test_cluster_script_runs_a_study_on_a_local_cluster(tmp_path):
    spec = importlib.util.spec_from_file_location("run_on_cluster", SCRIPT)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    path = write_study(tmp_path, "tiny", study={"seed": 5, "realizations": 24, "chunk_size": 8},
                       solver={"mode": "geodesic", "rings": 4}, uncertainty={"skew": {"dist": "uniform", "bounds": [-2, 2]}})
    out = tmp_path / "cluster"
    assert script.main([str(path), "--cluster", "local", "--cores", "2", "--out", str(out)]) == 0
    reference = run_ensemble(load_study(path), output_dir=tmp_path / "reference", scheduler="synchronous", progress=False)
    with open_ensemble(out) as got, open_ensemble(reference) as want:
        xr.testing.assert_identical(want.drop_attrs(deep=False), got.drop_attrs(deep=False))
    assert (out / "report" / "index.html").is_file()
