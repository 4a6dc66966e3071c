"""A seeded mutator over every kind of file uqdrape reads (issue 26): each case mutates a
valid file (bit flips, inserted tokens, extreme numbers in place of numbers, deletions,
duplications, truncation, values of another type) and reads it as a command would, through ``uqdrape.cli.main``
(its exception handling, exit codes and printing), with stdout and stderr captured at
the file descriptors (C libraries' messages included). Every case must end in exit 0, 2
or 3 with nothing or one line on stderr and no traceback.

The readers run in-process, one case in a few milliseconds (a subprocess costs a second
of start-up): the command is ``validate`` with its body replaced by the reader under test,
so the exit code and message are exactly those a user's command gets for that reader's
failure. A failure names the file type and the case's seed and keeps its input in a
``failures/`` folder beside the case's file (named in the message): a base written by a run
(run.json, a chunk) holds its own paths and dates, so ``_case(kind, seed)`` rebuilds the same
input only within one session. Slow suite: CASES per kind; the default suite runs SMOKE_CASES of each.
"""

from __future__ import annotations

import errno
import json
import random
import re
import socket
import subprocess
import sys
import time
from importlib import resources
from pathlib import Path

import pytest
import trimesh

import uqdrape.cli as cli
from uqdrape.ensemble.location import plan_chunks
from conftest import assert_one_line_error, write_study
from uqdrape.ensemble.lock import LOCK, run_lock
from uqdrape.ensemble import open_ensemble, read_manifest
from uqdrape.ensemble.location import MANIFEST
from uqdrape.ensemble.store import Folder, chunk_intact
from uqdrape.calibration import read_points
from uqdrape.experimental import read_experimental
from uqdrape.geometry import build
from uqdrape.material import load_material
from uqdrape.material.architecture import load_architecture
from uqdrape.material.sheartest import fit_card, read_rig
from uqdrape.study import load_study

#: Cases per file type in the slow suite, and in the default suite.
CASES = 1000
SMOKE_CASES = 25
#: A run.json accepted by its reader is also opened as a report opens the run (about 0.5 s
#: each): this many; and this many chunks that pass the resume check (every damaged one is).
MAX_OPENED = 5
MAX_INTACT_OPENED = 20

_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
#: A TOML ``key = value`` or JSON ``"key": value`` (the value up to the line's end or a comma).
_VALUE = re.compile(rb"(?:=|\":)\s*([^,\n]+)")
#: Values of the wrong type or shape, put in place of a whole value.
_VALUES = [b'"x"', b'""', b"[]", b"[1, 2]", b"[[0, 0]]", b"{}", b"{ a = 1 }", b"true", b"false", b'"../x"',
           b'"/etc/passwd"', b'"nan"', b"null", b"[0.0, 1e308]", rb'"\u0000"', b'"' + b"a" * 300 + b'"']
_EXTREME = [b"0", b"-0", b"-1", b"1", b"0.5", b"1e308", b"-1e308", b"1e309", b"1e-320", b"nan", b"inf", b"-inf",
            b"99999999999999999999999", b"4194305", b"2147483648", b"1e6", b"-1e-9", b"90", b"89.9999", b"3"]
_TOKENS = {
    "text": [b"[", b"]", b"[[x]]", b"{", b"}", b"=", b'"', b"'", b",", b"\n", b"#", b"\x00", b"\xff", b"\xfe",
             b"\xef\xbb\xbf", b"\\u0000", b"[" * 60, b"a.b.c = 1\n", b"x = 1\n", b"true", b'""', b"../",
             b"/etc/passwd", b"1979-05-27T07:32:00Z", b"\r\n", b"\t", b"-", b".", b"e", b"\\"],
    "json": [b"{", b"}", b"[", b"]", b'"', b":", b",", b"null", b"true", b"false", b"NaN", b"Infinity",
             b"1e999", b'"../../x"', b"[" * 3000, b"\\ud800", b"18446744073709551616", b"\x00", b"\xff"],
    "binary": [b"\x00", b"\xff", b"\x00" * 8, b"\xff" * 8, b"\x7f\xf0\x00\x00\x00\x00\x00\x00", b"\x89HDF\r\n\x1a\n",
               b"solid ", b"facet normal", b"nan"],
}


def _mutate(data: bytes, rng: random.Random, tokens: list[bytes]) -> bytes:
    """1-4 random edits of ``data``; a text file's numbers and values are the likeliest targets."""
    data = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        op = rng.choices(range(8), weights=(2, 3, 1, 4, 1, 1, 1, 3))[0]
        pos = rng.randrange(len(data) + 1)
        numbers = list(_NUMBER.finditer(data)) if op == 3 else []
        values = list(_VALUE.finditer(data)) if op == 7 else []
        if op == 0 and data:  # flip a bit
            data[min(pos, len(data) - 1)] ^= 1 << rng.randrange(8)
        elif op == 1:  # insert a token
            data[pos:pos] = rng.choice(tokens)
        elif op == 2:  # delete a run
            del data[pos:pos + rng.randint(1, 32)]
        elif op == 3 and numbers:  # an extreme number in place of a number
            m = rng.choice(numbers)
            data[m.start():m.end()] = rng.choice(_EXTREME)
        elif op == 4:  # truncate
            del data[pos:]
        elif op == 5 and data:  # duplicate a run
            start = rng.randrange(len(data))
            data[pos:pos] = data[start:start + rng.randint(1, 200)]
        elif op == 6 and data:  # overwrite 8 bytes
            data[pos:pos + 8] = rng.choice(tokens[:6]).ljust(8, b"\x00")[:8]
        elif op == 7 and values:  # a value of another type in place of a value
            m = rng.choice(values)
            data[m.start(1):m.end(1)] = rng.choice(_VALUES + _EXTREME)
    return bytes(data)


# ----------------------------------------------------------------------------- the files


def _shipped(*parts) -> bytes:
    return resources.files("uqdrape.material").joinpath(*parts).read_bytes()


@pytest.fixture(scope="module")
def bases(tmp_path_factory):
    """kind -> (the file a case overwrites, its valid bytes, tokens, read(path)): the
    readers as the commands call them."""
    d = tmp_path_factory.mktemp("fuzz")
    (d / "measured.csv").write_text("distance_mm,shear_deg,quadrant_sign,blankholder_force_N\n"
                                    "5,2.5,1,50\n10,-4.0,-1,50\n15,6,1,\n")
    study = write_study(d, "study", study={"realizations": 4, "chunk_size": 2},
                        uncertainty={"spacing": {"cv": 0.02}, "zero_angle": {"sd_deg": 1.0},
                                     "friction": {"dist": "normal", "mean": 0.2, "sd": 0.01}},
                        sampling={"plan": "latin_hypercube"}, report={"experimental_csv": "measured.csv",
                                                                      "histogram_nodes": [[1, 1]]})
    run = d / "run"
    run_study = write_study(d, "runstudy", study={"realizations": 4, "chunk_size": 2}, output={"directory": run})
    from uqdrape.workflow import run_study as run_it

    run_it(load_study(run_study), scheduler="synchronous", progress=False)
    resumed = load_study(run_study)
    chunk = sorted((run / "chunks").glob("*.nc"))[0]
    chunk_plan = plan_chunks(resumed, resumed.chunk_size)[0]
    mesh = trimesh.creation.icosphere(subdivisions=1, radius=50.0)
    mesh.export(d / "m.stl")
    mesh.export(d / "m.obj")
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    lock = json.dumps({"pid": int(gone.stdout), "host": socket.gethostname(),  # a run that died: taken over
                       "started": "2026-12-02 07:00:00 UTC"})
    opened = []

    def manifest(path):
        if read_manifest(path.parent) is not None:  # as a resuming run reads it, then a report
            Folder(path.parent).plan(resumed, resumed.to_dict(), resumed.chunk_size, resumed.realizations, True)
            if len(opened) < MAX_OPENED:
                opened.append(path)
                open_ensemble(path.parent).close()

    def intact(path):  # as a resuming run checks it, then as a report opens it (a report does not check)
        if chunk_intact(path, chunk_plan):
            if len(opened) >= MAX_INTACT_OPENED:
                return
            opened.append(path)
        with open_ensemble(run) as ds:
            ds.load()

    def locked(path):
        with run_lock(path.parent):
            pass

    shear = Path(__file__).parents[1] / "studies" / "sheartests"
    (d / "pf1.csv").write_bytes((shear / "pf1.csv").read_bytes())
    (d / "rig.toml").write_text('test = "picture_frame"\nside_mm = 145.0\n\n[fit]\nfriction = "subtract"\n\n'
                                '[[specimen]]\nfile = "pf1.csv"\n', encoding="utf-8")

    def fitted(rig):  # as `uqdrape materials fit` reads and fits
        fit_card(read_rig(rig), "fuzz", rig.name)

    points = Path(__file__).parents[1] / "studies" / "measurements" / "fibre-angles.csv"
    text, binary = _TOKENS["text"], _TOKENS["binary"]
    return {
        "rig": (d / "rig.toml", (d / "rig.toml").read_bytes(), text, fitted),
        "test_csv": (d / "pf1.csv", (d / "pf1.csv").read_bytes(), text, lambda path: fitted(d / "rig.toml")),
        "points_csv": (d / "points.csv", points.read_bytes(), text, read_points),
        "study": (study, study.read_bytes(), text, load_study),
        "card_toml": (d / "card.toml", _shipped("cards", "generic_woven.toml"), text, load_material),
        "card_csv": (d / "curve.csv", b"# measured\nangle_deg,ns_positive,ns_negative\n0,0,0\n10,5,3\n20,20,10\n"
                                      b"40,100,60\n55,900,400\n", _TOKENS["text"] + [b"ns_negative"], load_material),
        "architecture": (d / "arch.toml", _shipped("architectures", "fge106hd.toml"), text, load_architecture),
        "experimental_csv": (d / "measured.csv", (d / "measured.csv").read_bytes(), text, read_experimental),
        "run_json": (run / MANIFEST, (run / MANIFEST).read_bytes(), _TOKENS["json"], manifest),
        "run_lock": (run / LOCK, lock.encode(), _TOKENS["json"], locked),
        "chunk": (chunk, chunk.read_bytes(), binary, intact),
        "mesh": (d / "m.stl", (d / "m.stl").read_bytes(), binary, lambda path: build("mesh", path=str(path))),
        "mesh_obj": (d / "m.obj", (d / "m.obj").read_bytes(), text, lambda path: build("mesh", path=str(path))),
    }


def _case(bases, kind: str, seed: int) -> bytes:
    """The bytes of case ``seed`` of ``kind`` (a failure's seed rebuilds its input)."""
    _, data, tokens, _ = bases[kind]
    return _mutate(data, random.Random(f"{kind}-{seed}"), tokens)


@pytest.fixture()
def command(monkeypatch):
    """command(read) -> (exit code, stderr) of `uqdrape validate` whose body is ``read()``."""
    body = {}
    monkeypatch.setattr(cli, "cmd_validate", lambda args: body["read"]() or 0)
    parser = cli.build_parser()  # built once: argparse's 6 ms a call would be half the time
    monkeypatch.setattr(cli, "build_parser", lambda: parser)

    def run(read):
        body["read"] = read
        return cli.main(["validate", "fuzz"])

    return run


def _fuzz(bases, command, capfd, kind: str, cases: int) -> None:
    path, data, _, read = bases[kind]
    original = path.read_bytes() if path.exists() else data
    failures, codes = [], {}
    start = time.monotonic()
    try:
        for seed in range(cases):
            path.write_bytes(_case(bases, kind, seed))
            try:
                code = command(lambda: read(path) and None)
            except BaseException as err:  # what main() let through: a user would see a traceback
                code = f"{type(err).__name__}: {str(err)[:200]}"
            out, err = capfd.readouterr()
            codes[code] = codes.get(code, 0) + 1
            lines = err.splitlines()
            if code not in (0, 2, 3) or len(lines) > 1 or "Traceback" in err or (err and not err.endswith("\n")):
                failures.append((seed, code, err[:300]))
                kept = path.parent / "failures" / f"{kind}-{seed}{path.suffix}"
                kept.parent.mkdir(exist_ok=True)
                kept.write_bytes(path.read_bytes())
    finally:
        path.write_bytes(original)
        (path.parent / LOCK).unlink(missing_ok=True) if kind == "run_lock" else None
    print(f"{kind}: {cases} cases in {time.monotonic() - start:.1f} s, exit codes {codes}")
    assert failures == [], (f"{kind}: {len(failures)} of {cases} cases failed (inputs kept in "
                            f"{path.parent / 'failures'}), first: {failures[:3]}")


KINDS = ["study", "card_toml", "card_csv", "architecture", "experimental_csv", "run_json", "run_lock", "chunk",
         "mesh", "mesh_obj", "rig", "test_csv", "points_csv"]


@pytest.mark.parametrize("kind", KINDS)
def test_fuzz_smoke(bases, command, capfd, kind):
    _fuzz(bases, command, capfd, kind, SMOKE_CASES)


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_fuzz(bases, command, capfd, kind):
    _fuzz(bases, command, capfd, kind, CASES)


def test_the_mutator_is_seeded_and_mutates(bases):
    assert _case(bases, "study", 7) == _case(bases, "study", 7)
    assert len({_case(bases, "study", seed) for seed in range(50)}) >= 45
    assert all(_case(bases, "chunk", seed) != bases["chunk"][1] for seed in range(20))


# ----------------------------------------------------------------------------- what it found


@pytest.mark.parametrize("old, new, key", [
    (b"side_mm = 1.87", b"side_mm = 1e308", "side_mm"),  # seed 245: side^2 overflowed (OverflowError)
    (b"negative_ns = [60.0, 60.0]", b"negative_ns = [-1e308, 60.0]", "calibration.negative_ns"),  # seed 197
])
def test_an_architecture_value_past_its_range_is_one_line(tmp_path, old, new, key):
    data = _shipped("architectures", "fge106hd.toml")
    assert old in data
    path = tmp_path / "arch.toml"
    path.write_bytes(data.replace(old, new))
    with pytest.raises(ValueError) as err:
        load_architecture(path)
    assert_one_line_error(str(err.value), file=path)
    assert getattr(err.value, "key", None) and key in err.value.key


def test_chunks_that_no_longer_combine_are_a_corrupt_run(bases):
    """A chunk whose node index runs backwards opens, but the run's chunks no longer
    combine (xarray's ValueError, which named no file): a corrupt run folder, exit 3."""
    import xarray as xr

    chunk = bases["chunk"][0]
    original = chunk.read_bytes()
    try:
        with xr.open_dataset(chunk, engine="netcdf4", decode_cf=False) as ds:
            flipped = ds.load().assign_coords(i=ds["i"].values[::-1])
        flipped.to_netcdf(chunk, engine="netcdf4")
        with pytest.raises(OSError) as err:
            open_ensemble(chunk.parent.parent)
        assert err.value.errno == errno.EIO and str(chunk.parent) in err.value.filename
    finally:
        chunk.write_bytes(original)
