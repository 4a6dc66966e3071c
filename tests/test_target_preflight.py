"""The preflight of a run to a target (issue 29 item 3): memory and disk are checked for
its budget, ``max_realizations``, not only for its first round: a budget whose drapes
would not fit on the disk, or whose largest chunk would not fit in memory, is refused
before anything is draped, in one line naming ``study.max_realizations`` or
``study.chunk_size``, by ``uqdrape run`` and ``uqdrape validate`` alike."""

from __future__ import annotations

import shutil
from types import SimpleNamespace

import pytest

from uqdrape.cli import main
from uqdrape.study import StudyError, load_study
from uqdrape.workflow import preflight

from conftest import assert_one_line_error, write_study

#: rings 4: (2 x 4 + 1)^2 = 81 nodes a drape
NODES = 81


def goal_file(tmp_path, budget, chunk_size=8):
    """A target study of 16 geodesic hemisphere drapes in rounds up to ``budget``, one force level."""
    return write_study(tmp_path, "goal", study={"seed": 5, "realizations": 16, "chunk_size": chunk_size,
                                                 "target": {"qoi": "max_abs_shear", "statistic": "mean",
                                                            "half_width": 1e-9},
                                                 "max_realizations": budget},
                       solver={"mode": "geodesic", "rings": 4}, uncertainty={"spacing": {"cv": 0.02}})


@pytest.fixture
def disk_for(monkeypatch):
    """Make the disk hold exactly ``drapes`` drapes of NODES nodes (the preflight's estimate)."""
    def set_free(drapes):
        free = drapes * NODES * preflight.STORED_BYTES_PER_NODE
        monkeypatch.setattr(shutil, "disk_usage", lambda path: SimpleNamespace(free=free))
    return set_free


@pytest.mark.parametrize("command", ["run", "validate"])
def test_a_budget_that_would_not_fit_on_the_disk_is_refused_before_any_drape(tmp_path, capsys, disk_for, command):
    path = goal_file(tmp_path, budget=4096)
    disk_for(4095)  # room for the first round (16) and far more, not for the budget
    args = ["run", str(path), "--quiet", "--no-report", "--scheduler", "synchronous"] if command == "run" else \
        ["validate", str(path)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert_one_line_error(err, file=path, key="study.max_realizations", value="4096")
    assert "4,096 drapes of 81 nodes" in err
    assert not (tmp_path / "goal").exists()  # nothing written


def test_a_round_is_checked_with_the_drapes_its_later_rounds_may_add(tmp_path, disk_for):
    disk_for(32)
    check = preflight.run_preflight(load_study(goal_file(tmp_path, budget=32)), tmp_path / "goal", quiet=True)
    check(16, 0, 50.0)  # the first round's 16 drapes and the 16 its later rounds may add: exactly the disk
    with pytest.raises(StudyError, match=r"study.max_realizations = 32 is invalid: 33 drapes"):
        check(17, 0, 50.0)


def test_the_largest_chunk_of_the_budget_must_fit_in_memory(tmp_path, capsys, monkeypatch):
    # chunks of 64: the first round's 16 drapes fit, a later round's full chunk of 64 would not
    need = 64 * NODES * preflight.WORKING_BYTES_PER_NODE
    monkeypatch.setattr(preflight, "memory_bytes", lambda: 2 * need - 2)
    path = goal_file(tmp_path, budget=64, chunk_size=64)
    assert main(["validate", str(path)]) == 2
    assert_one_line_error(capsys.readouterr().err, file=path, key="study.chunk_size", value="64",
                          valid=("a chunk of 64 drapes",))
    monkeypatch.setattr(preflight, "memory_bytes", lambda: 2 * need)
    assert main(["validate", str(path)]) == 0
