"""Failing clean: one run per output folder, I/O faults and hostile inputs as one line on
stderr with the documented exit code, no half-written file, nothing left running after a
kill, and validation that refuses what a run would only find out after draping."""

from __future__ import annotations

import dataclasses
import json
import re
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import psutil
import pytest
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from uqdrape.cli import main as cli
from uqdrape.ensemble import open_ensemble
from uqdrape.ensemble import run as run_module
from uqdrape.ensemble.lock import LOCK, RunLocked
from uqdrape.study import load_study
from uqdrape.workflow import run_study

from conftest import assert_one_line_error, study_text, write_study
from uqdrape.files import toml_value


def _tiny(realizations=6, chunk_size=2, mode="geodesic", rings=4, failure_budget=None):
    """The sections of a tiny hemisphere study with a random zero angle (``write_study``'s keywords)."""
    return dict(study={"realizations": realizations, "chunk_size": chunk_size},
                solver={"mode": mode, "rings": rings, "failure_budget": failure_budget},
                uncertainty={"zero_angle": {"sd_deg": 2.0}})


def study_file(tmp_path, name="tiny", *, out=None, **tiny):
    """Write the tiny study (``_tiny``'s keywords); its output folder is tmp_path/name (or ``out``)."""
    return write_study(tmp_path, name, output={"directory": out or tmp_path / name}, **_tiny(**tiny))


# ----------------------------------------------------------------------------- one run per folder


def test_a_second_run_into_a_busy_folder_is_refused_and_deletes_nothing(tmp_path, capsys):
    path = study_file(tmp_path)
    out = run_study(path, scheduler="synchronous", progress=False)
    before = sorted(p.name for p in (out / "chunks").iterdir())
    (out / LOCK).write_text(json.dumps({"pid": os.getpid(), "host": os.uname().nodename, "started": "now"}))
    with pytest.raises(RunLocked, match="another run"):
        run_study(path, scheduler="synchronous", resume=False, progress=False)
    assert cli(["run", str(path), "--no-resume", "--no-report", "--scheduler", "synchronous"]) == 3
    err = capsys.readouterr().err
    assert_one_line_error(err, file=out, valid=[f"pid {os.getpid()}"])
    assert sorted(p.name for p in (out / "chunks").iterdir()) == before  # --no-resume deleted nothing


def test_a_stale_lock_of_a_dead_process_is_taken_over(tmp_path):
    path = study_file(tmp_path)
    out = tmp_path / "tiny"
    out.mkdir()
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    (out / LOCK).write_text(json.dumps({"pid": gone.pid, "host": os.uname().nodename, "started": "then"}))
    run_study(path, scheduler="synchronous", progress=False)
    assert not (out / LOCK).exists()  # released after the run


# ----------------------------------------------------------------------------- I/O faults


@pytest.mark.slow  # end to end: a reference run, a failing run and its resume
def test_a_full_disk_is_one_line_leaves_no_part_file_and_resumes_equal(tmp_path, capsys, monkeypatch):
    path = study_file(tmp_path)
    reference = run_study(study_file(tmp_path, "ref", out=tmp_path / "ref"), scheduler="synchronous", progress=False)
    real, usage = xr.Dataset.to_netcdf, shutil.disk_usage
    written = []

    def fills_the_disk(self, target, *args, **kwargs):
        if len(written) == 1:  # the second chunk: netCDF writes part of it and fails as it does
            Path(target).write_bytes(b"CDF\x01 half")
            written.append(None)
            raise RuntimeError("NetCDF: HDF error")
        written.append(target)
        return real(self, target, *args, **kwargs)

    monkeypatch.setattr(xr.Dataset, "to_netcdf", fills_the_disk)
    monkeypatch.setattr(shutil, "disk_usage", lambda p: SimpleNamespace(free=0) if None in written else usage(p))
    # -q: stderr holds only the error (without it, the first progress line comes first)
    assert cli(["run", str(path), "--no-report", "--scheduler", "synchronous", "-q"]) == 3
    err = capsys.readouterr().err
    assert_one_line_error(err)
    assert re.search(r"tiny/chunks/r\d{7}-\d{7}\.nc: the disk is full$", err.strip()), err
    assert list((tmp_path / "tiny" / "chunks").glob("*.part")) == []
    monkeypatch.undo()
    out = run_study(path, scheduler="synchronous", progress=False)
    with open_ensemble(out) as a, open_ensemble(reference) as b:
        xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))


def test_a_corrupt_chunk_is_named_with_what_to_do(tmp_path, capsys):
    out = run_study(study_file(tmp_path), scheduler="synchronous", progress=False)
    victim = sorted((out / "chunks").glob("*.nc"))[1]
    victim.write_bytes(victim.read_bytes()[:200])
    assert cli(["report", str(out)]) == 3
    err = capsys.readouterr().err
    assert_one_line_error(err, file=victim, valid=["is not what the run wrote", "run the study again"])


def test_an_unreachable_scheduler_is_one_line_within_its_timeout(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(run_module, "SCHEDULER_TIMEOUT", 1)
    start = time.monotonic()
    assert cli(["run", str(study_file(tmp_path)), "--scheduler", "tcp://127.0.0.1:9", "--no-report"]) == 3
    assert time.monotonic() - start < 15
    err = capsys.readouterr().err
    assert_one_line_error(err)
    assert "tcp://127.0.0.1:9" in err and "cannot reach the dask scheduler within 1 s" in err


@pytest.mark.parametrize("target", ["file", "under-file"])
def test_an_output_folder_that_cannot_be_a_folder_is_refused_at_validation(tmp_path, capsys, target):
    blocker = tmp_path / "blocker"
    blocker.write_text("a file")
    out = blocker if target == "file" else blocker / "run"
    assert cli(["validate", str(study_file(tmp_path, out=out))]) == 2
    err = capsys.readouterr().err
    assert_one_line_error(err, key="output.directory", valid=["is a file, not a folder"])


def test_a_study_whose_net_leaves_the_mould_is_refused_before_draping(tmp_path, capsys):
    path = study_file(tmp_path, rings=40)  # 2 x 40 x 5 mm = 400 mm of net on a 50 mm dome
    assert cli(["run", str(path), "--scheduler", "synchronous"]) == 2
    err = capsys.readouterr().err
    assert_one_line_error(err, key="solver.rings", value="40", valid=["cannot be placed", "off_mould"])
    assert "failure_budget = 0.5" in err and not (tmp_path / "tiny").exists()
    # the run checks again with its own first realisation (an energy drape may fail where the
    # nominal geodesic one did not): a study changed after validation stops there
    study = load_study(study_file(tmp_path, "ok"))
    study = dataclasses.replace(study, solver=dataclasses.replace(study.solver, rings=40))
    with pytest.raises(ValueError, match=r"of the nodes of realisation 0 cannot be placed, more than "
                                         r"solver.failure_budget = 0.5 \(node status: ok \d+, .*off_mould"):
        run_study(study, scheduler="synchronous", progress=False)
    assert list((tmp_path / "ok" / "chunks").glob("*")) == []


@pytest.mark.slow  # end to end: a 34-ring run and its report
def test_a_run_within_its_failure_budget_reports_the_status_counts_instead_of_failing(tmp_path, capsys, unrasterised):
    # 2 x 34 x 5 mm of net on a 50 mm dome with a 100 mm flange: most nodes fall off the mould
    path = study_file(tmp_path, rings=34, realizations=2, failure_budget=0.99)
    assert cli(["run", str(path), "--scheduler", "synchronous", "--quiet"]) == 0
    assert capsys.readouterr().err == ""  # no warning from a plot of the degenerate ensemble
    report = tmp_path / "tiny" / "report"
    status = json.loads((report / "summary.json").read_text())["node_status"]
    assert sum(status.values()) == 2 * 69 * 69 and status["off_mould"] > 0 and status["dependent"] > 0
    assert 0 < status["ok"] < 0.5 * 2 * 69 * 69
    page = (report / "index.html").read_text()
    assert f"not placed: dependent {status['dependent']:,}, off_mould {status['off_mould']:,}" in page
    # the geodesic drape ignores the zero-angle field: no spread, so no histogram or convergence plot
    assert "No histograms or convergence plot" in page
    assert not (report / "histograms.png").exists() and not (report / "convergence.png").exists()


# ----------------------------------------------------------------------------- hostile inputs

#: (section, key, value as TOML) replacements or additions to the base study.
HOSTILE_VALUES = {
    ("study", "seed"): ["-1", "9223372036854775808", "9223372036854775807", "0", "1.5", '"x"', "true", "[]"],
    ("study", "realizations"): ["0", "-3", "1000000000", "2.5", '"10"', "{}"],
    ("study", "chunk_size"): ["0", "100000000", "nan", '"big"'],
    ("study", "name"): ['""', '"a b"', '"../x"', "7"],
    ("geometry", "radius"): ["0", "-50", "nan", "inf", '"r"', "1e300"],
    ("geometry", "kind"): ['"sphere"', "3", '""'],
    ("fabric", "spacing_mm"): ["0", "-5", "inf", "1e-9", '"5"', "1000"],
    ("fabric", "material"): ['"nope"', '"../../etc/passwd"', '"card.csv"', "1"],
    ("fabric", "crossover"): ["[0]", "[1e9, 0]", '["a", 0]', "[nan, 0]", "0"],
    ("fabric", "pre_shear_deg"): ["90", "-90", "1e9", '"x"'],
    ("process", "blankholder_force_N"): ["-1", "1e12", "[]", "[1, 1]", '"100"', "nan", "[0, 1e5]"],
    ("process", "friction"): ["-0.1", "1e6", "inf", '"0.2"'],
    ("process", "sectors"): ["[]", "[0, 0]", "[-1, 2]", '"8"'],
    ("process", "blankholder_model"): ['"circular"', "1"],
    ("solver", "rings"): ["0", "-2", "1000000", "2.5"],
    ("solver", "mode"): ['"fast"', "1"],
    ("solver", "tolerance_deg"): ["0", "-1", "nan"],
    ("solver", "max_iterations"): ["0", "1.5"],
    ("solver", "failure_budget"): ["-0.5", "2", '"half"'],
    ("uncertainty.zero_angle", "sd_deg"): ["-1", "nan", '"2"'],
    ("uncertainty.zero_angle", "correlation"): ['"pink"', "1"],
    ("uncertainty.friction", "dist"): ['"cauchy"', '"normal"', "3"],
    ("uncertainty.orientation", "bounds"): ["[5, -5]", "[0]", '["a", "b"]'],
    ("sampling", "plan"): ['"sobol"', '"grid"', "0", '"latin_hypercube"'],
    ("sensitivity", "method"): ['"sobol"', '"fast"'],
    ("sensitivity", "base_samples"): ["64", "-1"],
    ("report", "histogram_nodes"): ["[[99, 99]]", "[[1]]", '"all"'],
    ("report", "experimental_csv"): ['"missing.csv"', "1", '"bad.csv"'],
    ("output", "directory"): ['""', "5"],
    ("output", "float32"): ['"yes"', "1", "true"],
    ("fabric", "orientation_deg"): ["720", "-1e9", '"north"'],
}
#: Whole files that are not study files.
HOSTILE_FILES = {
    "empty": b"",
    "garbage": bytes(range(256)),
    "latin-1": "[study]\nname = \"d\xe9j\xe0\"\n".encode("latin-1"),
    "no-sections": b"name = 1\n",
    "array-section": b"[[study]]\nname = \"x\"\n",
    "unknown-section": b"[studdy]\nname = \"x\"\n",
    "utf-16-without-mark": "[study]\nname = \"x\"\n".encode("utf-16-le"),
    "nul-bytes": b"[study]\x00\x00\n",
}


def _set(text: str, section: str, key: str, value: str) -> str:
    """The base study with ``key`` of ``[section]`` set to ``value`` (added if absent)."""
    lines = text.splitlines()
    head = f"[{section}]"
    if head not in lines:
        lines += ["", head]
    start = lines.index(head)
    end = next((k for k in range(start + 1, len(lines)) if lines[k].startswith("[")), len(lines))
    body = [line for line in lines[start + 1:end] if not line.startswith(f"{key} =")]
    return "\n".join(lines[:start + 1] + [f"{key} = {value}"] + body + lines[end:]) + "\n"


def _cases():
    for (section, key), values in HOSTILE_VALUES.items():
        for value in values:
            yield f"{section}.{key}={value}", ("study", section, key, value)
    for name, data in HOSTILE_FILES.items():
        yield f"file-{name}", ("file", data)
    flags = [["--spacing", "0"], ["--spacing", "-1"], ["--rings", "0"], ["--rings", "x"],
             ["--geometry", "sphere"], ["--param", "radius=-5"], ["--param", "radius"], ["--param", "nope=1"],
             ["--mode", "energy"], ["--mode", "energy", "--material", "nope"], ["--blankholder-force", "-1"],
             ["--friction", "-1"], ["--pre-shear", "95"], ["--crossover", "1e9", "0"], ["--tolerance", "0"],
             ["--blankholder-model", "circular"], ["--out", "/proc/uqdrape/x"]]
    for k, f in enumerate(flags):
        yield f"drape{k}:{' '.join(f)}", ("drape", f)


CASES = dict(_cases())


def test_there_are_at_least_120_hostile_cases():
    assert len(CASES) >= 120


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_a_hostile_input_ends_in_success_or_one_line(tmp_path, capsys, case):
    kind, *what = CASES[case]
    if kind == "drape":
        argv = ["drape", "--rings", "3", "--out", str(tmp_path / "d"), *what[0]]
    else:
        argv = ["validate", str(_hostile_study(tmp_path, case))]
    try:
        code = cli(argv)
    except SystemExit as stop:  # argparse's own usage errors
        code = stop.code
    err = capsys.readouterr().err
    assert code in (0, 2, 3), code
    assert "Traceback" not in err
    if code:
        assert err.count("\n") == 1 or err.startswith("usage:"), err
    assert "np.float64" not in err


def _hostile_study(tmp_path: Path, case: str) -> Path:
    """The study file of a hostile study case, written under ``tmp_path``."""
    kind, *what = CASES[case]
    path = tmp_path / "hostile.toml"
    (tmp_path / "bad.csv").write_text("distance_mm,shear_deg\n1,2\n")  # no quadrant_sign column
    if kind == "file":
        path.write_bytes(what[0])
    else:
        section, key, value = what
        base = study_file(tmp_path, "base").read_text(encoding="utf-8")
        path.write_text(_set(base, section, key, value), encoding="utf-8")
    return path


@pytest.mark.slow
def test_every_hostile_study_that_validates_also_runs(tmp_path, capsys, unrasterised):
    """What validate accepts, run does not refuse after draping (tiny geodesic ensembles)."""
    accepted = []
    for k, (case, (kind, *_)) in enumerate(CASES.items()):
        if kind == "drape":
            continue
        folder = tmp_path / str(k)
        folder.mkdir()
        path = _hostile_study(folder, case)
        if cli(["validate", str(path)]) == 0:
            accepted.append(case)
            assert cli(["run", str(path), "--scheduler", "synchronous"]) == 0, (case, capsys.readouterr().err)
    capsys.readouterr()
    assert len(accepted) >= 5, accepted


# ----------------------------------------------------------------------------- kills (slow)


def _run_in_background(path: Path, tmp_path: Path):
    log = open(tmp_path / "run.log", "w")
    return subprocess.Popen([sys.executable, "-m", "uqdrape.cli", "run", str(path), "--workers", "2", "--no-report"],
                            stdout=log, stderr=subprocess.STDOUT, cwd=tmp_path)


def _chunks(out: Path) -> list[str]:
    return sorted(p.name for p in (out / "chunks").glob("*.nc")) if (out / "chunks").is_dir() else []


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_a_killed_run_leaves_no_process_and_resumes_to_the_same_ensemble(tmp_path, sig):
    path = study_file(tmp_path, realizations=40, chunk_size=4, mode="energy", rings=10)
    proc = _run_in_background(path, tmp_path)
    out = tmp_path / "tiny"
    deadline = time.monotonic() + 300
    while not _chunks(out) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert _chunks(out), (tmp_path / "run.log").read_text()
    family = psutil.Process(proc.pid).children(recursive=True)
    assert family, "the run should have worker processes"
    os.kill(proc.pid, sig)
    proc.wait(timeout=30)
    if sig == signal.SIGTERM:
        assert proc.returncode == 130
        assert (tmp_path / "run.log").read_text().strip().endswith("run again to resume")
    time.sleep(10)
    alive = [p for p in family if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
    assert alive == []
    after = _chunks(out)
    time.sleep(3)
    assert _chunks(out) == after  # no chunk written by an orphan
    assert list((out / "chunks").glob("*.part")) == [] or sig == signal.SIGKILL  # SIGKILL: the next run clears it
    # in this process: equal to the worker processes' numbers bitwise (test_ensemble), and no pool to start
    resumed = run_study(path, scheduler="synchronous", progress=False)
    whole = run_study(study_file(tmp_path, "whole", realizations=40, chunk_size=4, mode="energy", rings=10),
                      scheduler="synchronous", progress=False)
    with open_ensemble(resumed) as a, open_ensemble(whole) as b:
        xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))


# ----------------------------------------------------------------------------- fuzzing (slow)

_SCALARS = st.one_of(st.just(""), st.booleans(), st.integers(-10**20, 10**20), st.floats(allow_nan=True),
                     st.text(max_size=12))
_KEYS = st.sampled_from(["name", "seed", "realizations", "chunk_size", "kind", "radius", "material", "spacing_mm",
                         "crossover", "blankholder_force_N", "friction", "sectors", "blankholder_model", "mode",
                         "rings", "sd_deg", "cv", "dist", "bounds", "plan", "method", "directory", "x"])
_SECTIONS = st.sampled_from(["study", "geometry", "fabric", "process", "solver", "uncertainty.zero_angle",
                             "uncertainty.friction", "sampling", "sensitivity", "report", "output", "other"])


@st.composite
def _documents(draw):
    """A study file: the tiny base study with some keys replaced or added, or noise."""
    if draw(st.integers(0, 9)) == 0:
        return draw(st.binary(max_size=200))
    text = study_text("/tmp", "fuzz", output={"directory": "/tmp/fuzz-out"}, **_tiny(realizations=4, rings=3))
    for _ in range(draw(st.integers(1, 4))):
        value = draw(st.one_of(_SCALARS, st.lists(_SCALARS, max_size=3)))
        text = _set(text, draw(_SECTIONS), draw(_KEYS), toml_value(value))
    return text.encode("utf-8")


@pytest.mark.slow
@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                     HealthCheck.too_slow])
@given(document=_documents())
def test_fuzzed_study_files_never_raise_a_traceback(tmp_path_factory, document):
    path = tmp_path_factory.mktemp("fuzz") / "fuzz.toml"
    path.write_bytes(document)
    err = subprocess_free_validate(path)
    assert "Traceback" not in err and err.count("\n") <= 1, err


def subprocess_free_validate(path: Path) -> str:
    """Run ``uqdrape validate PATH`` in this process; return its stderr."""
    import contextlib
    import io

    buffer = io.StringIO()
    with contextlib.redirect_stderr(buffer), contextlib.redirect_stdout(io.StringIO()):
        code = cli(["validate", str(path)])
    assert code in (0, 2), (code, buffer.getvalue())
    return buffer.getvalue()


@pytest.fixture()
def bad_request_store():
    """The URL of an HTTP server on 127.0.0.1 that answers every request 400 Bad Request."""
    import http.server
    import threading

    class Refuse(http.server.BaseHTTPRequestHandler):
        def refuse(self):
            self.send_response(400)
            self.send_header("Content-Length", "0")
            self.end_headers()

        do_GET = do_HEAD = do_PUT = do_POST = do_DELETE = refuse

        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Refuse)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}/x"
    server.shutdown()
    server.server_close()


@pytest.mark.parametrize("command", ["report", "run"])
def test_a_store_answering_http_400_is_one_line_exit_3(tmp_path, capsys, bad_request_store, command):
    args = [bad_request_store] if command == "report" else [str(write_study(tmp_path, **_tiny())), "--out",
                                                             bad_request_store, "-q"]
    assert cli([command, *args]) == 3
    assert_one_line_error(capsys.readouterr().err, file=bad_request_store, valid=["HTTP 400"])
