"""Every reader of a user's file (study, material card and its CSV, shear-test rig and its
CSV, fibre-angle CSV, image, measured part, experimental CSV, mesh in each format family,
FE mesh, trim curve) answers a file that is not what it expects -- a password file named
by mistake, binary junk, a valid start followed by a foreign line -- with one line naming
the file, and never with a line of that file: the file may not be the user's. A FIFO or a
folder in place of any of them is refused at once, never read (which would block)."""

from __future__ import annotations

import os
import threading

import pytest
from conftest import write_study

from uqdrape.cli import main

PASSWD = ("root:x:0:0:root:/root:/bin/bash\ndaemon:x:1:1:daemon:/usr/sbin:/usr/sbin/nologin\n"
          "secret_token = 'hunter2-Zq9'\n")
#: Foreign contents: (name, text or bytes). Each is written under every reader's suffix.
FOREIGN = [
    ("passwd", PASSWD),
    ("binary", bytes(range(256)) * 8),
    ("xml", '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid"><zz9Tag/></VTKFile>\n'),
    ("header-then-foreign", "x_mm,y_mm,angle_deg,fibre_set\n1,2,45,1\nroot:x:0:0:root:/root:/bin/bash\n"),
    ("numbers-then-foreign", "0,0\n1,0\n1,1\nroot:x:0:0:root:/root:/bin/bash,daemon:x:1:1\n"),
    ("rig-header-then-foreign", "displacement_mm,force_n\n0,0\n1,2\nroot:x:0:0:root:/root:/bin/bash,zz9\n"),
    ("card-header-then-foreign", "angle_deg,ns_positive\n0,0\nroot:x:0:0:root:/root:/bin/bash,zz9\n"),
]


#: Pieces of the foreign lines that no message may hold, whatever it quotes of a line.
SECRETS = ["root:x", "daemon:x", "hunter2", "zz9"]


def _lines(content) -> list[str]:
    """What of a foreign file an error must not show: its lines of 4 or more characters
    and the SECRETS."""
    text = content if isinstance(content, str) else content.decode("latin-1")
    return [line.strip() for line in text.splitlines() if len(line.strip()) >= 4] + SECRETS


def _write(path, content):
    (path.write_text if isinstance(content, str) else path.write_bytes)(content)
    return path


@pytest.fixture(scope="module")
def drape_nc(tmp_path_factory):
    out = tmp_path_factory.mktemp("drape") / "d"
    assert main(["drape", "--geometry", "hemisphere", "--param", "radius=30", "--spacing", "5", "--rings", "6",
                 "--out", str(out), "-q"]) == 0
    return out.with_suffix(".nc")


def _commands(tmp_path, bad, drape_nc):
    """(suffix, argv) per reader, ``bad`` standing for the file under test (its suffix added)."""
    study = write_study(tmp_path, "host")
    return {
        "study": (".toml", lambda f: ["validate", str(f)]),
        "card": (".toml", lambda f: ["materials", str(f)]),
        "card csv": (".csv", lambda f: ["materials", str(f)]),
        "card's curve csv": (".csv", lambda f: ["materials", str(_write(
            tmp_path / "card.toml", f'name = "c"\nlocking_angle_deg = 50.0\n[shear]\ncsv = "{f.name}"\n'))]),
        "rig": (".toml", lambda f: ["materials", "fit", str(f), "--out", str(tmp_path / "o.toml")]),
        "rig's test csv": (".csv", lambda f: ["materials", "fit", str(_write(
            tmp_path / "rig.toml", f'test = "picture_frame"\nside_mm = 150.0\n[[specimen]]\nfile = "{f.name}"\n')),
            "--out", str(tmp_path / "o.toml")]),
        "fibre-angle csv": (".csv", lambda f: ["calibrate", str(f), "--out", str(tmp_path / "o.toml")]),
        "image": (".png", lambda f: ["calibrate", str(f), "--mm-per-px", "0.1", "--out", str(tmp_path / "o.toml")]),
        "measured part": (".csv", lambda f: ["calibrate", "--drapes", str(f), "--study", str(study), "--parameter",
                                             "process.friction=0.1:0.3", "--out", str(tmp_path / "o.toml")]),
        "experimental csv": (".csv", lambda f: ["validate", str(write_study(
            tmp_path, "exp", report={"experimental_csv": f.name}))]),
        **{f"mesh {suffix}": (suffix, lambda f: ["validate", str(write_study(
            tmp_path, "mesh", geometry={"kind": "mesh", "path": f.name, "radius": None}))])
           for suffix in (".stl", ".obj", ".vtu", ".inp", ".msh")},
        "drape mesh": (".vtu", lambda f: ["drape", "--geometry", "mesh", "--param", f"path={f}",
                                          "--out", str(tmp_path / "d")]),
        "fe mesh": (".inp", lambda f: ["export", str(drape_nc), "--to", "fe", "--mesh", str(f),
                                       "--out", str(tmp_path / "fe")]),
        "trim": (".csv", lambda f: ["export", str(drape_nc), "--to", "cut", "--trim", str(f),
                                    "--out", str(tmp_path / "cut")]),
    }


READERS = ["study", "card", "card csv", "card's curve csv", "rig", "rig's test csv", "fibre-angle csv", "image",
           "measured part", "experimental csv", "mesh .stl", "mesh .obj", "mesh .vtu", "mesh .inp", "mesh .msh",
           "drape mesh", "fe mesh", "trim"]


@pytest.mark.parametrize("reader", READERS)
def test_a_foreign_file_is_one_line_without_its_content(tmp_path, capsys, drape_nc, reader):
    for name, content in FOREIGN:
        suffix, argv = _commands(tmp_path, None, drape_nc)[reader]
        bad = _write(tmp_path / f"{name}{suffix}", content)
        code = main(argv(bad))
        out, err = capsys.readouterr()
        assert code == 2, (reader, name, code, out, err)
        assert len(err.splitlines()) == 1 and "Traceback" not in err, (reader, name, err)
        shown = [line for line in _lines(content) if line in out + err]
        assert not shown, (reader, name, shown, err)


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_a_fifo_or_folder_in_place_of_a_file_is_refused_without_blocking(tmp_path, capsys, drape_nc, reader, kind):
    suffix, argv = _commands(tmp_path, None, drape_nc)[reader]
    bad = tmp_path / f"special{suffix}"
    os.mkfifo(bad) if kind == "fifo" else bad.mkdir()
    writer = None
    if kind == "fifo":  # should the reader open it, this writer unblocks it after 30 s, so the test ends
        writer = threading.Timer(30.0, lambda: open(bad, "wb").close())
        writer.daemon = True
        writer.start()
    try:
        code = main(argv(bad))
    finally:
        if writer is not None:
            opened = writer.finished.is_set()  # the timer ran: the reader was waiting
            writer.cancel()
    err = capsys.readouterr().err
    assert code == 2, (reader, code, err)
    assert len(err.splitlines()) == 1 and str(bad) in err, err
    if writer is not None:
        assert not opened, "the reader waited on the FIFO"


@pytest.mark.parametrize("what", ["study", "mesh"])
def test_a_file_of_200_mb_or_a_device_is_refused_from_its_size_or_kind_unread(tmp_path, capsys, what):
    big = tmp_path / ("big.toml" if what == "study" else "big.stl")
    with open(big, "wb") as f:
        f.truncate(200 * 2**20)  # sparse: 200 MB of zeros that take no disk
    study = big if what == "study" else write_study(tmp_path, "mesh", geometry={"kind": "mesh", "path": big.name,
                                                                                 "radius": None})
    assert main(["validate", str(study)]) == 2
    assert main(["validate", "/dev/zero"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and "larger than" in err[0] and str(big) in err[0], err
    assert "/dev/zero" in err[1] and "not a regular file" in err[1], err
