"""A rare probability as a study's report quantity (issue 29 item 2): ``[study] rare =
{qoi, threshold, cov, max_drapes}`` is estimated after the run at every force level by
``uqdrape.reliability.importance_sampling`` on the study's own limit state, kept in
``rare.json`` (a resume keeps it, a changed request redoes it), printed by ``uqdrape run``
and in the report's headline table and summary.json with its CoV and drapes; refused in
one line where it cannot apply. The ``lock_margin`` QoI it is meant for (P(any cell
locked) = P(lock_margin > 1)) agrees with the lock flags."""

from __future__ import annotations

import json

import numpy as np
import pytest

from uqdrape.cli import main
from uqdrape.ensemble import drape_inputs, sampled_inputs
from uqdrape.reliability import importance_sampling
from uqdrape.stats import realization_qois
from uqdrape.study import load_study
from uqdrape.workflow import run_report, run_study
from uqdrape.workflow.rare import RARE_FILE, RARE_STREAM, drape_limit_state, factor_values, read_rare

from conftest import assert_one_line_error, write_study

#: Geodesic drapes of a 50 mm dome, 6 rings, iid spacing (cv 2 %) and a skew factor (sd 1
#: deg): 313 standard variables. The line shear's 0.99 quantile over 20,000 plain drapes
#: is 10.89 deg (its nominal 8.11 deg, sd 1.24 deg).
UNCERTAIN = {"spacing": {"cv": 0.02}, "skew": {"dist": "normal", "mean": 0.0, "sd": 1.0}}
RARE = {"qoi": "mean_shear_positive", "threshold": 10.9, "cov": 0.2, "max_drapes": 5000}


def rare_file(tmp_path, rare=RARE, uncertainty=None, **sections):
    return write_study(tmp_path, "rare", study={"seed": 1, "realizations": 8, "chunk_size": 8, "rare": rare},
                       solver={"mode": "geodesic", "rings": 6}, uncertainty={**UNCERTAIN, **(uncertainty or {})},
                       **sections)


def test_a_study_estimates_its_rare_probability_and_reports_it(tmp_path, capsys, unrasterised):
    path = rare_file(tmp_path)
    assert main(["run", str(path), "--scheduler", "synchronous", "--no-report"]) == 0
    out = tmp_path / "rare"
    record = json.loads((out / RARE_FILE).read_text())
    level = record["levels"][0]
    # the estimator on the study's own limit state, with the study's stream: bitwise
    study = load_study(path)
    g, d = drape_limit_state(study, "mean_shear_positive", 10.9, 50.0)
    seed = int(np.random.SeedSequence([1, RARE_STREAM, 0]).generate_state(1)[0])
    direct = importance_sampling(g, d, seed=seed, cov=0.2, max_calls=5000, features=factor_values(study))
    assert (level["probability"], level["cov"], level["drapes"], level["method"]) == (
        direct.probability, direct.cov, direct.calls, "importance")
    assert record["variables"] == d == 313 and level["cov"] <= 0.2 and level["drapes"] <= 5000
    # about 1e-2 by construction (the 0.99 quantile of 20,000 plain drapes): within 3 stated CoV
    assert abs(level["probability"] / 0.01 - 1) <= 3 * level["cov"]
    err = capsys.readouterr().err
    line = (f"rare: P(mean_shear_positive >= 10.9 deg) at 50 N = {level['probability']:.3g} (CoV "
            f"{level['cov']:.2f}, {level['drapes']:,} drapes, importance sampling at the most probable point of subset "
            "levels, 313 standard variables)")
    assert line in err.splitlines()
    index = run_report(out)
    summary = json.loads(index.with_name("summary.json").read_text())
    assert summary["rare"]["levels"] == record["levels"] and summary["rare"]["threshold"] == 10.9
    html = index.read_text()
    assert "P(mean_shear_positive &gt;= 10.9 deg) at 50 N" in html and f"{level['drapes']:,} drapes" in html
    # a resumed run keeps the estimate; it is not of another threshold
    stamp = (out / RARE_FILE).stat().st_mtime_ns
    assert main(["run", str(path), "--scheduler", "synchronous", "--no-report"]) == 0
    assert "rare probability already estimated" in capsys.readouterr().err
    assert (out / RARE_FILE).stat().st_mtime_ns == stamp
    assert read_rare(load_study(rare_file(tmp_path, {**RARE, "threshold": 11.5})), out) is None
    # the report of a study no longer asking for it does not show the old record
    run_study(write_study(tmp_path, "rare", study={"seed": 1, "realizations": 8, "chunk_size": 8},
                          solver={"mode": "geodesic", "rings": 6}, uncertainty=UNCERTAIN),
              scheduler="synchronous", progress=False)
    assert "rare" not in json.loads(run_report(out).with_name("summary.json").read_text())


@pytest.mark.parametrize("rare, sections, key, valid", [
    ({**RARE, "qoi": "any_locked"}, {}, "study.rare.qoi", ("lock_margin", "max_abs_shear")),
    ({**RARE, "cov": 0.0}, {}, "study.rare.cov", ("0 < cov < 1",)),
    ({**RARE, "max_drapes": 500}, {}, "study.rare.max_drapes", (">= 1000",)),
    ({k: v for k, v in RARE.items() if k != "threshold"}, {}, "study.rare.threshold", ()),
    (RARE, {"uncertainty": {"zero_angle": {"sd_deg": 2.0, "sd_dof": 30}}}, "uncertainty.zero_angle.sd_dof",
     ("a [study] rare probability",)),
    (RARE, {"design": {"variables": "force", "force_bounds_N": [0.0, 100.0], "objective": "p_locked"}},
     "study.rare", ("without [design]",)),
])
def test_a_rare_request_that_cannot_apply_is_one_line(tmp_path, capsys, rare, sections, key, valid):
    path = rare_file(tmp_path, rare, **sections)
    assert main(["validate", str(path)]) == 2
    assert_one_line_error(capsys.readouterr().err, file=path, key=key, valid=valid)


def test_lock_margin_is_above_one_exactly_where_a_cell_is_locked(tmp_path):
    # a skew of sd 3 deg on an 8-ring dome locks a few of 64 drapes (locking at 50 deg)
    study = load_study(write_study(tmp_path, "lock", study={"seed": 1, "realizations": 64, "chunk_size": 64},
                                   solver={"mode": "geodesic", "rings": 8},
                                   uncertainty={"spacing": {"cv": 0.02},
                                                "skew": {"dist": "normal", "mean": 0.0, "sd": 3.0}}))
    ds = drape_inputs(study, np.arange(64), sampled_inputs(study, np.arange(64)))
    q = realization_qois(ds, ["lock_margin", "any_locked"])
    locked = q["any_locked"].values > 0
    assert 0 < locked.sum() < 64
    np.testing.assert_array_equal(q["lock_margin"].values > 1, locked)
    rel = ds["cell_shear"] - ds["gamma0"]
    assert float(q["lock_margin"][0]) == float(np.nanmax(np.abs(rel.isel(realization=0)))) / 50.0
    assert q["lock_margin"].attrs["units"] == "1"


@pytest.mark.slow  # ~20 s at load 1: 20,000 plain drapes and one estimate
def test_a_study_rare_probability_agrees_with_plain_monte_carlo(tmp_path):
    study = load_study(rare_file(tmp_path, {**RARE, "cov": 0.1}))
    g, d = drape_limit_state(study, "mean_shear_positive", 0.0)
    U = np.random.default_rng(7).standard_normal((20_000, d))
    value = -np.concatenate([g(part) for part in np.array_split(U, 10)])
    p_mc = np.mean(value >= 10.9)  # about 0.01: CoV 7 %
    run_study(study, scheduler="synchronous", progress=False)
    level = json.loads((tmp_path / "rare" / RARE_FILE).read_text())["levels"][0]
    assert level["method"] == "importance" and level["cov"] <= 0.1
    assert abs(level["probability"] / p_mc - 1) <= 3 * np.hypot(level["cov"], np.sqrt((1 - p_mc) / (p_mc * 20_000)))


def test_a_threshold_no_drape_reaches_is_a_bound_said_in_one_line(tmp_path, capsys, monkeypatch):
    # subset simulation's 30 levels cut to 2: the line shear never reaches 80 deg on this dome;
    # the record is "no failure in N drapes: P < bound", strict JSON, said on stderr even with -q
    import uqdrape.workflow.rare as rare
    real = rare.importance_sampling
    monkeypatch.setattr(rare, "importance_sampling", lambda *a, **k: real(*a, **{**k, "max_levels": 2}))
    path = rare_file(tmp_path, {**RARE, "threshold": 80.0})
    assert main(["run", str(path), "--scheduler", "synchronous", "--no-report", "-q"]) == 0
    text = (tmp_path / "rare" / RARE_FILE).read_text()
    level = json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in {RARE_FILE}"))["levels"][0]
    assert level["method"] == "below" and level["cov"] == 0.0 and level["beta"] is None
    # two levels of 500 (the second 450 moved points at most): the bound is the smaller of
    # -ln(0.05) / 500 and the levels' P(g <= their last threshold)
    assert level["drapes"] <= 950 and 0 < level["probability"] <= -np.log(0.05) / 500
    err = capsys.readouterr().err.splitlines()
    assert (f"rare: warning: P(mean_shear_positive >= 80) at 50 N: no drape reached the threshold in "
            f"{level['drapes']:,} drapes: P < {level['probability']:.2g}, an upper bound, not an estimate") in err
    html = run_report(tmp_path / "rare").read_text()
    assert f"&lt; {level['probability']:.3g}" in html and "an upper bound, not an estimate" in html


def test_certain_failure_is_p_one(tmp_path, capsys):
    # every drape's line shear is above 0 deg: one level of plain drapes, P = 1, no warning
    path = rare_file(tmp_path, {**RARE, "threshold": 0.0})
    assert main(["run", str(path), "--scheduler", "synchronous", "--no-report", "-q"]) == 0
    level = json.loads((tmp_path / "rare" / RARE_FILE).read_text())["levels"][0]
    assert (level["probability"], level["cov"], level["method"], level["drapes"]) == (1.0, 0.0, "montecarlo", 500)
    assert "warning" not in capsys.readouterr().err


@pytest.mark.parametrize("threshold, below", [(10.9, False), (12.5, True)])
def test_the_budget_is_a_hard_limit_and_a_result_not_to_trust_says_so(tmp_path, capsys, threshold, below):
    # CoV 0.01 within 1,000 drapes: at about 1e-2 (10.9 deg) the budget stops the estimate
    # above its target; at about 1e-3 (12.5 deg) it stops the subset levels before failure
    path = rare_file(tmp_path, {**RARE, "threshold": threshold, "cov": 0.01, "max_drapes": 1000})
    assert main(["run", str(path), "--scheduler", "synchronous", "--no-report", "-q"]) == 0
    level = json.loads((tmp_path / "rare" / RARE_FILE).read_text())["levels"][0]
    assert level["drapes"] <= 1000 and (level["method"] == "below") == below
    assert level["note"].endswith("the budget ran out")
    said = [line for line in capsys.readouterr().err.splitlines() if line.startswith("rare: warning: ")]
    html = run_report(tmp_path / "rare").read_text()
    if below:
        assert len(said) == 1 and said[0].endswith("an upper bound, not an estimate")
        assert "an upper bound, not an estimate" in html
    else:
        assert level["cov"] > 0.01 and len(said) == 1 and "not to be trusted" in said[0]
        assert said[0].endswith(f"CoV {level['cov']:.2f} above the target 0.01 ({level['note']})")
        assert f"NOT TRUSTED: above the target 0.01: {level['note']}" in html
