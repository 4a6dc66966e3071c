"""Fixtures and helpers shared by the test modules.

``write_study`` is the one builder of study files; ``assert_one_line_error`` the one check
of an error message's essentials. The suite caches compiled bytecode even where the environment sets
PYTHONDONTWRITEBYTECODE: without it every test process (pytest-xdist's workers included)
recompiles uqdrape and re-rewrites the test modules' asserts, 5 s of an 8 s collection on
the 2-core machine. The caches go to the ``__pycache__`` folders, beside numba's.
"""

from __future__ import annotations

import copy
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from matplotlib.figure import Figure
from PIL import Image

from uqdrape.files import toml_text

sys.dont_write_bytecode = False


@pytest.fixture()
def unrasterised(monkeypatch):
    """Report figures built in full but not rasterised: each PNG is a 1 x 1 white pixel.

    Rasterising is most of a report's time (about 1 s a figure on the 2-core machine). Tests
    of what a report holds (which figures, numbers, links, notes, figure sizes) use this;
    the pixels of every figure are checked by the tests that draw them
    (``test_write_report_links_and_summary_numbers`` and the figure tests of test_report).
    Returns the list of Figures "saved", in order.
    """
    saved = []

    def savefig(self, fname, *args, **kwargs):
        saved.append(self)
        Image.new("RGB", (1, 1), "white").save(fname, format="png")

    monkeypatch.setattr(Figure, "savefig", savefig)
    return saved


# -- study files -----------------------------------------------------------------------

#: The smallest valid study: a geodesic drape of 4 rings on a 50 mm dome, nothing random.
STUDY = {
    "study": {"name": "tiny", "seed": 3, "realizations": 6, "chunk_size": 2},
    "geometry": {"kind": "hemisphere", "radius": 50.0},
    "fabric": {"material": "generic_woven", "spacing_mm": 5.0},
    "process": {"blankholder_force_N": 50.0},
    "solver": {"mode": "geodesic", "rings": 4},
}


def write_study(folder, name="tiny", **sections) -> Path:
    """Write ``folder/name.toml`` (the text of ``study_text``); returns the path."""
    path = Path(folder) / f"{name}.toml"
    path.write_text(study_text(folder, name, **sections), encoding="utf-8")
    return path


def study_text(folder, name="tiny", **sections) -> str:
    """A study named ``name`` writing to ``folder/name``: STUDY with each keyword's table merged
    into the section of that name (sub-tables such as ``uncertainty={"spacing": {"cv": 0.01}}``
    merge the same way; None drops a key, a sub-table or a section), as TOML text."""
    doc = _merged(copy.deepcopy(STUDY), {"study": {"name": name}, "output": {"directory": Path(folder) / name}})
    return toml_text(_merged(doc, sections))


def _merged(base: dict, changes: dict) -> dict:
    for key, value in changes.items():
        if value is None:
            base.pop(key, None)
        elif isinstance(value, dict):
            base[key] = _merged(base.get(key, {}) if isinstance(base.get(key), dict) else {}, value)
        else:
            base[key] = value
    return base




# -- error messages --------------------------------------------------------------------

def assert_one_line_error(text: str, *, file=None, key=None, value=None, valid=()) -> None:
    """Check what a user needs to fix an input, not the wording: ``text`` (an exception's
    message or a command's stderr) is one line without a traceback, names ``file``, names
    ``key`` as a whole dotted key (as ``key = value`` when ``value``, TOML text, is given)
    and holds each string of ``valid`` (the valid values or range)."""
    lines = text.splitlines()
    assert len(lines) == 1 and lines[0].strip() and text in (lines[0], lines[0] + "\n"), text
    assert "Traceback" not in text, text
    if file is not None:
        assert str(file) in text, (file, text)
    if key is not None:
        named = key if value is None else f"{key} = {value}"
        assert re.search(rf"(?<![\w.]){re.escape(named)}(?![\w])", text), (named, text)
    for part in valid:
        assert part in text, (part, text)


# -- an S3 server on 127.0.0.1 -----------------------------------------------------------

#: Bytes the bucket "full" of the ``s3`` server takes before it answers every further
#: upload as a Ceph gateway over its bucket quota (HTTP 403, QuotaExceeded).
FULL_BUCKET_BYTES = 200_000
_QUOTA_EXCEEDED = (b'<?xml version="1.0" encoding="UTF-8"?><Error><Code>QuotaExceeded</Code>'
                   b'<Message>bucket quota exceeded</Message></Error>')


def _with_quota(app):
    """``app`` (moto's WSGI application) with the bucket "full" limited to FULL_BUCKET_BYTES."""
    used = [0]

    def quota(environ, start_response):
        if environ["REQUEST_METHOD"] in ("PUT", "POST") and environ.get("PATH_INFO", "").startswith("/full/"):
            used[0] += int(environ.get("CONTENT_LENGTH") or 0)
            if used[0] > FULL_BUCKET_BYTES:
                start_response("403 Forbidden", [("Content-Type", "application/xml"),
                                                 ("Content-Length", str(len(_QUOTA_EXCEEDED)))])
                return [_QUOTA_EXCEEDED]
        return app(environ, start_response)

    return quota


@pytest.fixture(scope="module")
def s3():
    """moto's S3 server on 127.0.0.1, started here, with the buckets "runs", "readonly"
    (a bucket policy denies PutObject) and "full" (FULL_BUCKET_BYTES of quota); the AWS_*
    environment points at it for the module (worker processes inherit it). Yields an
    s3fs filesystem on it."""
    import json
    import threading
    import urllib.request

    pytest.importorskip("moto.server")
    from moto.server import DomainDispatcherApplication, MotoRequestHandler, create_backend_app
    from werkzeug.serving import make_server

    server = make_server("127.0.0.1", 0, _with_quota(DomainDispatcherApplication(create_backend_app)), threaded=True,
                         request_handler=MotoRequestHandler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    endpoint = f"http://127.0.0.1:{server.server_port}"
    urllib.request.urlopen(urllib.request.Request(f"{endpoint}/moto-api/reset", method="POST")).close()  # moto's
    # state is per process, not per server: start each module with no buckets
    with pytest.MonkeyPatch.context() as env:
        for key, value in {"AWS_ENDPOINT_URL": endpoint, "AWS_ACCESS_KEY_ID": "testing",
                           "AWS_SECRET_ACCESS_KEY": "testing", "AWS_DEFAULT_REGION": "us-east-1"}.items():
            env.setenv(key, value)
        import s3fs

        s3fs.S3FileSystem.clear_instance_cache()
        fs = s3fs.S3FileSystem(client_kwargs={"endpoint_url": endpoint})
        for bucket in ("runs", "readonly", "full"):
            fs.mkdir(bucket)
        deny = {"Version": "2012-10-17", "Statement": [{"Effect": "Deny", "Principal": "*", "Action": "s3:PutObject",
                                                        "Resource": "arn:aws:s3:::readonly/*"}]}
        fs.call_s3("put_bucket_policy", Bucket="readonly", Policy=json.dumps(deny))
        yield fs
        s3fs.S3FileSystem.clear_instance_cache()
    server.shutdown()


@pytest.fixture()
def no_s3_credentials(s3, monkeypatch):
    """The ``s3`` server's environment without credentials anywhere botocore looks."""
    import s3fs

    for key in ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY"):
        monkeypatch.delenv(key)
    for key in ("AWS_SHARED_CREDENTIALS_FILE", "AWS_CONFIG_FILE"):
        monkeypatch.setenv(key, "/nonexistent")
    monkeypatch.setenv("AWS_EC2_METADATA_DISABLED", "true")
    s3fs.S3FileSystem.clear_instance_cache()
    yield
    s3fs.S3FileSystem.clear_instance_cache()


def _cf_tables(tmp_path) -> list[str]:
    """Empty CF tables (no standard names are used) so the checker needs no download."""
    tables = {"-s": ("std.xml", "standard_name_table", "last_modified"),
              "-a": ("area.xml", "area_type_table", "date"),
              "-r": ("region.xml", "standardized_region_list", "date")}
    args = []
    for flag, (name, root, date) in tables.items():
        (tmp_path / name).write_text(f'<?xml version="1.0"?><{root}><version_number>0</version_number>'
                                     f"<{date}>2026-01-01</{date}></{root}>")
        args += [flag, str(tmp_path / name)]
    return args


def _cf_checker_missing(why: str):
    """Skip where the CF checker cannot run; in CI (``CI`` set, as ``.ci/run`` runs) fail:
    there the README's CF claim must be checked, not skipped."""
    if os.environ.get("CI"):
        pytest.fail(f"{why}: .ci/run installs it (Debian's libudunits2-0, the test extra's cfchecker)")
    pytest.skip(why)


def assert_cf_compliant(path, tmp_path) -> None:
    """The CF checker (cfchecker's ``cfchecks``, CF-1.8) finds no error or warning in the
    netCDF file ``path``; skipped where it cannot run (see ``_cf_checker_missing``)."""
    try:
        import cfchecker  # noqa: F401
        import cfunits  # noqa: F401  (needs the UDUNITS-2 C library)
    except (ImportError, FileNotFoundError, OSError) as err:
        _cf_checker_missing(f"the CF checker cannot be imported ({type(err).__name__}: {str(err).splitlines()[0]}); "
                            "install the UDUNITS-2 library (Debian: apt install libudunits2-0) and "
                            "pip install 'uqdrape[test]'")
    # the checker's script sits next to the interpreter running the tests, venv or not
    cfchecks = Path(sys.executable).parent / "cfchecks"
    if not cfchecks.is_file():
        _cf_checker_missing(f"{cfchecks} does not exist")
    out = subprocess.run([cfchecks, *_cf_tables(tmp_path), "-v", "1.8", str(path)], capture_output=True, text=True,
                         timeout=120).stdout
    assert "ERRORS detected: 0" in out and "WARNINGS given: 0" in out, out
