"""Every QoI of the registry (``uqdrape.stats.QOIS``) works where a study can ask for it,
or ``validate`` refuses it in one line (issue 39): a ``[study] rare`` and a ``[design]
rare`` on it, a run to a target on its mean, and a sensitivity study ranking it, each
on tiny geodesic drapes. ``max_draw_in`` once failed on every ensemble after its drapes
(the flat blank of an ensemble's (force, realisation) batch)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

from uqdrape import design
from uqdrape.cli import main
from uqdrape.ensemble import open_ensemble
from uqdrape.stats import QOIS
from uqdrape.study.spec import RARE_QOIS
from uqdrape.workflow import open_sensitivity
from uqdrape.workflow.rare import RARE_FILE

from conftest import assert_one_line_error, write_study
from test_design import write

UNCERTAIN = {"spacing": {"cv": 0.02}, "skew": {"dist": "normal", "mean": 0.0, "sd": 1.0}}
#: A threshold every drape exceeds: one level of 500 plain drapes, P = 1 (the QoI is computed
#: on every one of them).
EVERY = -1.0e9


def run(path, *args) -> int:
    return main(["run", str(path), "--scheduler", "synchronous", "--no-report", "-q", *args])


@pytest.mark.parametrize("qoi", QOIS)
def test_a_study_rare_probability_of_every_qoi(tmp_path, capsys, qoi):
    path = write_study(tmp_path, "r", study={"seed": 1, "realizations": 4, "chunk_size": 4,
                                             "rare": {"qoi": qoi, "threshold": EVERY, "max_drapes": 1000}},
                       uncertainty=UNCERTAIN)
    if qoi not in RARE_QOIS:
        assert main(["validate", str(path)]) == 2
        assert_one_line_error(capsys.readouterr().err, file=path, key="study.rare.qoi", valid=RARE_QOIS)
        return
    assert run(path) == 0
    level = json.loads((tmp_path / "r" / RARE_FILE).read_text())["levels"][0]
    assert (level["probability"], level["method"], level["drapes"]) == (1.0, "montecarlo", 500)
    assert np.isfinite(open_ensemble(tmp_path / "r")["x"].values).any()


@pytest.mark.parametrize("qoi", [q if q in ("max_draw_in", "lock_margin", "any_locked") else
                                 pytest.param(q, marks=pytest.mark.slow) for q in QOIS])  # ~10 s each
def test_a_design_rare_constraint_on_every_qoi(tmp_path, capsys, qoi):
    text = ('variables = "force"\nforce_bounds_N = [0.0, 100.0]\nobjective = "q95_max_abs_shear"\n'
            'statistic = "estimate"\ntolerance_N = 40.0\nmax_evaluations = 4\n'
            f'rare = {{qoi = "{qoi}", threshold = {EVERY}, max_probability = 1e-2, max_drapes = 1000}}\n')
    path = write(tmp_path, text, realizations=4)
    if qoi not in RARE_QOIS:
        assert main(["validate", str(path)]) == 2
        assert_one_line_error(capsys.readouterr().err, file=path, key="design.rare.qoi", valid=RARE_QOIS)
        return
    assert run(path) == 0
    ds = xr.load_dataset(tmp_path / "out" / design.DESIGN_FILE)
    assert np.all(ds["rare_probability"].values == 1.0) and np.all(ds["feasible"].values == 0)


@pytest.mark.parametrize("qoi", QOIS)
def test_a_run_to_a_target_on_every_qoi(tmp_path, qoi):
    path = write_study(tmp_path, "t", study={"seed": 2, "realizations": 8, "chunk_size": 8, "max_realizations": 16,
                                             "target": {"qoi": qoi, "statistic": "mean", "half_width": 1e9}},
                       uncertainty=UNCERTAIN)
    assert run(path) == 0
    assert open_ensemble(tmp_path / "t").sizes["realization"] == 8  # the first round meets so wide a target


@pytest.mark.parametrize("qoi", QOIS)
def test_a_sensitivity_study_of_every_qoi(tmp_path, qoi):
    path = write_study(tmp_path, "s", study={"seed": 3, "realizations": 4, "chunk_size": 16},
                       uncertainty=UNCERTAIN, sensitivity={"method": "morris", "base_samples": 10, "qoi": [qoi]})
    assert run(path) == 0
    indices, _ = open_sensitivity(tmp_path / "s")
    assert indices["qoi"].values.tolist() == [qoi]
