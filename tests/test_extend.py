"""Extendable samples (issue 29): a finished run resumed with more realisations keeps its
chunks, the last partial one as it is, and adds the new realisations, bitwise the run of
the larger number from the start; plans whose points depend on N, and fewer realisations
than a run holds, are refused in one line."""

from __future__ import annotations

import dataclasses

import pytest
import xarray as xr

from uqdrape.cli import main
from uqdrape.ensemble import open_ensemble, read_manifest
from uqdrape.study import load_study
from uqdrape.workflow import run_study

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
                                         r"study.realizations >= 16"):
        run_study(dataclasses.replace(study, realizations=12), scheduler="synchronous", progress=False)
