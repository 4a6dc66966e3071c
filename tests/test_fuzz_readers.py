"""Two readers of a run's own JSON files, fuzzed (issue 40): the rare-event record
(``rare.json``: ``workflow.rare.parse_rare``) and the run manifest (``run.json``:
``ensemble.location.parse_manifest``). Whatever the bytes (noise, other JSON, a record
with a field replaced or removed), each gives the record or one OSError or ValueError of one
line, which the CLI prints as its one-line error; a rare record it gives is one the report
and a resume can show. The fuzz is in the slow suite and prints its hypothesis seed;
FUZZ_SEED=<seed> replays it. Regressions found on the way run in the default suite."""

from __future__ import annotations

import json
import math
import os
import random

import pytest
from hypothesis import HealthCheck, given, note, seed, settings
from hypothesis import strategies as st

from uqdrape.ensemble.location import parse_manifest
from uqdrape.report import rare_rows
from uqdrape.study import load_study
from uqdrape.workflow.rare import RARE_FILE, parse_rare, rare_key, read_rare, untrusted

from conftest import assert_one_line_error, write_study

#: The seed of this session's fuzz: printed once, and in the report of a failing example.
SEED = int(os.environ.get("FUZZ_SEED") or random.SystemRandom().randrange(2**32))


@pytest.fixture(scope="module")
def fuzz_seed():
    print(f"hypothesis seed {SEED} (FUZZ_SEED={SEED} replays it)")

#: A rare-event record as ``rare_probabilities`` writes it: two force levels, an estimate
#: and an upper bound.
RECORD = {"key": "0" * 64, "qoi": "lock_margin", "threshold": 1.0, "cov": 0.1, "max_drapes": 20000, "variables": 313,
          "levels": [{"force": 0.0, "probability": 1.02e-3, "cov": 0.09, "drapes": 2650, "method": "importance",
                      "beta": 3.08, "subset_probability": 1.1e-3, "subset_cov": 0.3, "note": ""},
                     {"force": 126.0, "probability": 1.6e-3, "cov": 0.0, "drapes": 2156, "method": "below",
                      "beta": None, "subset_probability": 1.6e-3, "subset_cov": 0.0, "note": "no drape failed"}]}
#: A run manifest as a run writes it (the study record trimmed to its required shape).
MANIFEST = {"study": {"study": {"name": "tiny", "seed": 1}, "geometry": {"kind": "hemisphere"}},
            "chunks": ["r0000000-0000002.nc", "f001-r0000003-0000005.nc"], "chunk_size": 3, "wall_time_s": 1.5,
            "uqdrape": "0.0"}

_JSON = st.recursive(st.none() | st.booleans() | st.integers(-10**30, 10**30) | st.floats() | st.text(max_size=8),
                     lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                                 max_size=3),
                     max_leaves=8)


def _edited(document: dict):
    """``document`` with one field, at the top or one level down, replaced by any JSON
    value or removed; or its JSON text cut short."""
    @st.composite
    def edit(draw):
        doc = json.loads(json.dumps(document))
        table = doc
        if draw(st.booleans()):
            nested = [v for v in doc.values() if isinstance(v, dict)] + \
                     [v for v in doc.values() if isinstance(v, list) and v and isinstance(v[0], dict)]
            inner = draw(st.sampled_from(nested))
            table = draw(st.sampled_from(inner)) if isinstance(inner, list) else inner
        key = draw(st.sampled_from(sorted(table)))
        if draw(st.integers(0, 4)) == 0:
            del table[key]
        else:
            table[key] = draw(_JSON)
        text = json.dumps(doc).encode()  # NaN and Infinity as Python's json writes them
        return text[:draw(st.integers(0, len(text)))] if draw(st.integers(0, 9)) == 0 else text
    return edit()


def _inputs(document: dict):
    return st.one_of(st.binary(max_size=300), _JSON.map(lambda v: json.dumps(v).encode()), _edited(document))


def _read(parse, data: bytes):
    """``parse(data, "runs/x/NAME")``: the record, or None after checking its error is one
    line of the kinds the CLI prints as one."""
    try:
        return parse(data, "runs/x/file.json")
    except (OSError, ValueError) as err:
        text = err.strerror if isinstance(err, OSError) and err.errno else str(err)
        assert text and "\n" not in text and "Traceback" not in text, text
        return None


def _fuzzed(base):
    """The slow suite's fuzz of a reader: 3,000 inputs made from ``base``, seeded with SEED."""
    def wrap(test):
        return pytest.mark.slow(seed(SEED)(settings(max_examples=3000, deadline=None,
                                                    suppress_health_check=[HealthCheck.too_slow])(
            given(data=_inputs(base))(test))))
    return wrap


@_fuzzed(RECORD)
def test_fuzzed_rare_records_give_the_record_or_one_line(fuzz_seed, data):
    note(f"hypothesis seed {SEED} (FUZZ_SEED={SEED} replays it)")
    record = _read(parse_rare, data)
    if record is not None:  # what was accepted, the report and a resume can show
        rare_rows(record)
        for level in record["levels"]:
            untrusted(record, level)


@_fuzzed(MANIFEST)
def test_fuzzed_run_manifests_give_the_manifest_or_one_line(fuzz_seed, data):
    note(f"hypothesis seed {SEED} (FUZZ_SEED={SEED} replays it)")
    _read(parse_manifest, data)


def test_the_fuzz_bases_are_read_as_they_are():
    assert parse_rare(json.dumps(RECORD).encode(), "rare.json") == RECORD
    assert parse_manifest(json.dumps(MANIFEST).encode(), "run.json") == MANIFEST


@pytest.mark.parametrize("data, why", [
    (b"[]", "not a JSON object"),  # was AttributeError: 'list' object has no attribute 'get'
    (b"\xff{}", "not JSON text"),  # was UnicodeDecodeError, naming no file
    (b"[" * 100_000, "not JSON text"),  # was RecursionError
    (None, '"qoi"'),  # the study's key and nothing else: was KeyError in the report
    ({"qoi": "x"}, '"qoi"'),  # was KeyError in the report
    ({"threshold": math.nan}, '"threshold"'),  # was shown as P(lock_margin >= nan)
    ({"levels": [{**RECORD["levels"][0], "method": "guess"}]}, "the method"),  # was KeyError in the report
    ({"levels": [{**RECORD["levels"][0], "cov": None}]}, "its cov"),  # was TypeError in untrusted
])
def test_a_damaged_rare_record_is_one_line_naming_it(tmp_path, capsys, data, why):
    """``rare.json`` in a run folder, as resume and report read it (``read_rare``): any
    damage is one OSError naming the file; the study's own record with a field changed
    too (its key still matching)."""
    study = load_study(write_study(tmp_path, study={"rare": {"qoi": "lock_margin", "threshold": 1.0}}))
    key = rare_key(study)
    if data is None:
        data = json.dumps({"key": key}).encode()
    elif isinstance(data, dict):
        data = json.dumps({**RECORD, "key": key, **data}).encode()
    run = tmp_path / "run"
    run.mkdir()
    (run / RARE_FILE).write_bytes(data)
    with pytest.raises(OSError) as err:
        read_rare(study, run)
    assert err.value.filename == str(run / RARE_FILE)
    assert_one_line_error(err.value.strerror, valid=["not a uqdrape rare-event record", why])
    (run / RARE_FILE).write_text(json.dumps({**RECORD, "key": key}))
    assert read_rare(study, run) == {**RECORD, "key": key}
