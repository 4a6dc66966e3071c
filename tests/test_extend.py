"""Extendable samples and runs to a target accuracy (issue 29): a finished run resumed
with more realisations keeps its chunks, the last partial one as it is, and adds the new
realisations, bitwise the run of the larger number from the start; plans whose points
depend on N, and fewer realisations than a run holds, are refused in one line. A
``[study] target`` run adds rounds until its interval is narrow enough or its budget is
spent, and says which."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import xarray as xr
from scipy import stats

from uqdrape.cli import main
from uqdrape.ensemble import open_ensemble, read_manifest
from uqdrape.stats import realization_qois
from uqdrape.study import StudyError, load_study
from uqdrape.workflow import run_report, run_study

from conftest import assert_one_line_error, write_study


def study_file(tmp_path, name, realizations, plan="monte_carlo", out="out"):
    """Study ``ext`` in the file tmp_path/name/ext.toml: a small random hemisphere sweep
    (two force levels), spacing and zero-angle fields and a friction factor, chunks of 24
    (so 64 realisations end in a partial chunk)."""
    folder = tmp_path / name
    folder.mkdir(exist_ok=True)
    return write_study(folder, "ext", study={"seed": 5, "realizations": realizations, "chunk_size": 24},
                       process={"blankholder_force_N": [0.0, 50.0], "friction": 0.2},
                       solver={"mode": "geodesic", "rings": 4},
                       uncertainty={"spacing": {"cv": 0.01}, "zero_angle": {"sd_deg": 3.0},
                                    "friction": {"dist": "uniform", "bounds": [0.1, 0.3]}},
                       sampling={"plan": plan}, output={"directory": tmp_path / out})


def test_64_then_80_realisations_equal_80_from_scratch(tmp_path):
    out = run_study(study_file(tmp_path, "small", 64), scheduler="synchronous", progress=False)
    partial = out / "chunks" / "f001-r0000048-0000063.nc"
    stamp = partial.stat().st_mtime_ns
    run_study(study_file(tmp_path, "large", 80), scheduler="synchronous", progress=False)
    assert partial.stat().st_mtime_ns == stamp  # the last partial chunk is kept as it is
    assert read_manifest(out)["chunks"] == [f"{level}-r{a:07d}-{b:07d}.nc" for level in ("f000", "f001")
                                            for a, b in ((0, 23), (24, 47), (48, 63), (64, 79))]
    scratch = run_study(study_file(tmp_path, "scratch", 80, out="scratch"), scheduler="synchronous",
                        progress=False)
    assert read_manifest(scratch)["chunks"][2] == "f000-r0000048-0000071.nc"  # another cut, same numbers
    with open_ensemble(out) as extended, open_ensemble(scratch) as fresh:
        assert extended.sizes["realization"] == 80
        xr.testing.assert_identical(extended.drop_attrs(deep=False).load(), fresh.drop_attrs(deep=False).load())
        assert extended.attrs["study_realizations"] == 80  # the run's study is the extended one


def test_a_plan_that_does_not_extend_and_fewer_realisations_are_refused(tmp_path, capsys):
    run_study(study_file(tmp_path, "lhs", 16, plan="latin_hypercube"), scheduler="synchronous", progress=False)
    larger = study_file(tmp_path, "lhs", 20, plan="latin_hypercube")
    assert main(["run", str(larger), "--quiet", "--no-report", "--workers", "1"]) == 2
    assert_one_line_error(capsys.readouterr().err, key="sampling.plan", value="'latin_hypercube'",
                          valid=("monte_carlo", "--no-resume"))
    study = load_study(study_file(tmp_path, "mc", 16, out="mc"))
    run_study(study, scheduler="synchronous", progress=False)
    with pytest.raises(ValueError, match=r"holds 16 realisations, more than the 12 asked for: set "
                                         r"realizations >= 16 in \[study\], or run again without resuming"):
        run_study(dataclasses.replace(study, realizations=12), scheduler="synchronous", progress=False)


# ----------------------------------------------------------------------------- target runs


def target_file(tmp_path, half_width, budget=96, statistic="mean", qoi="max_abs_shear", plan="monte_carlo",
                realizations=16):
    folder = tmp_path / "target"
    folder.mkdir(exist_ok=True)
    target = {"qoi": qoi, "statistic": statistic, "half_width": half_width}
    return write_study(folder, "goal", study={"seed": 5, "realizations": realizations, "chunk_size": 8,
                                              "target": target, "max_realizations": budget},
                       solver={"mode": "geodesic", "rings": 4}, uncertainty={"spacing": {"cv": 0.02}},
                       sampling={"plan": plan}, output={"directory": tmp_path / "goal"})


def t_half_width(values, confidence=0.95):
    """Student-t half-width of the mean of ``values``, written out (scipy's t quantile)."""
    return stats.t.ppf(0.5 + confidence / 2, values.size - 1) * values.std(ddof=1) / np.sqrt(values.size)


def test_a_target_run_stops_at_the_first_round_below_its_target(tmp_path, unrasterised):
    # the half-width of 16 drapes, from the target's own first round with an unreachable target
    first = run_study(target_file(tmp_path, 1e-9, budget=16), scheduler="synchronous", progress=False)
    start = read_manifest(first)["target"]
    assert start["stopped_by"] == "budget" and start["realizations"] == 16
    goal = start["half_width_reached"] / 2  # about 4x the drapes: a few rounds
    out = run_study(target_file(tmp_path, goal, budget=512), scheduler="synchronous", progress=False, resume=False)
    record = read_manifest(out)["target"]
    rounds = [(r["realizations"], r["half_width"][0]) for r in record["rounds"]]
    assert len(rounds) >= 2 and record["stopped_by"] == "target"
    assert all(h > goal for _, h in rounds[:-1]) and rounds[-1][1] <= goal  # stopped at the first one below
    assert [n for n, _ in rounds] == sorted({n for n, _ in rounds}) and all(n % 8 == 0 for n, _ in rounds)
    with open_ensemble(out) as ds:
        values = realization_qois(ds, ["max_abs_shear"])["max_abs_shear"].isel(blankholder_force=0).values
    assert values.size == record["realizations"] == rounds[-1][0]
    assert record["half_width_reached"] == pytest.approx(t_half_width(values), rel=1e-12)
    summary = json.loads(run_report(out).with_name("summary.json").read_text())
    assert summary["attrs"]["target_stopped_by"] == "target"
    assert summary["attrs"]["target_rounds"] == str([n for n, _ in rounds])  # list attributes as text
    # run again: it resumes where it stopped, one round with nothing to drape
    again = read_manifest(run_study(target_file(tmp_path, goal, budget=512), scheduler="synchronous",
                                    progress=False))["target"]
    assert [r["realizations"] for r in again["rounds"]] == [rounds[-1][0]] and again["stopped_by"] == "target"


def test_a_target_run_stops_at_its_budget(tmp_path):
    out = run_study(target_file(tmp_path, 1e-9, budget=40, statistic="probability", qoi="any_locked"),
                    scheduler="synchronous", progress=False)
    record = read_manifest(out)["target"]
    assert record["stopped_by"] == "budget" and [r["realizations"] for r in record["rounds"]] == [16, 32, 40]
    # nothing locks on this dome: P = 0 with the Wilson upper limit z^2 / (n + z^2), half of it
    z = stats.norm.ppf(0.975)
    assert record["rounds"][-1]["estimate"] == [0.0]
    assert record["half_width_reached"] == pytest.approx(z**2 / (40 + z**2) / 2, rel=1e-12)
    # an interrupted last round (no target record yet, a chunk not written) resumes at its size
    manifest = read_manifest(out)
    del manifest["target"]
    (out / "run.json").write_text(json.dumps(manifest))
    (out / "chunks" / "r0000032-0000039.nc").unlink()
    again = read_manifest(run_study(target_file(tmp_path, 1e-9, budget=40, statistic="probability",
                                                qoi="any_locked"), scheduler="synchronous", progress=False))["target"]
    assert [r["realizations"] for r in again["rounds"]] == [40] and again["half_width_reached"] == record[
        "half_width_reached"]


@pytest.mark.parametrize("changes, key, valid", [
    ({"max_realizations": None}, "study.target", ("max_realizations",)),
    ({"statistic": "probability"}, "study.target.statistic", ("any_locked",)),
    ({"plan": "latin_hypercube"}, "sampling.plan", ("monte_carlo",)),
    ({"budget": 8}, "study.max_realizations", (">= 16",)),
])
def test_target_keys_are_checked(tmp_path, changes, key, valid):
    budget = changes.pop("budget", 96)
    path = target_file(tmp_path, 0.1, budget=budget, **{k: v for k, v in changes.items() if k != "max_realizations"})
    if "max_realizations" in changes:
        path.write_text(path.read_text().replace("max_realizations = 96\n", ""))
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key=key, valid=valid)
