"""A command's stderr holds uqdrape's own one-line message or nothing: no numpy, trimesh,
meshio, xarray or dask warnings, and absurd values refused before they overflow
(issue 26). Each command runs in a subprocess, as a user runs it."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings

import pytest
import trimesh

import uqdrape.cli as cli
from conftest import assert_one_line_error


def uqdrape(*argv, cwd, warnings=None):
    """``uqdrape ARGV`` in a fresh interpreter: (exit code, stderr). ``warnings``: the
    PYTHONWARNINGS it starts with (None: unset, as for most users)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    if warnings is not None:
        env["PYTHONWARNINGS"] = warnings
    done = subprocess.run([sys.executable, "-m", "uqdrape.cli", "-q", *argv], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=240)
    return done.returncode, done.stderr


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """A folder with a drape file (d.nc, 3 rings) and an STL whose first vertex is at 1e30 mm."""
    path = tmp_path_factory.mktemp("quiet")
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=50.0)
    vertices = mesh.vertices.copy()
    vertices[0] = [1e30, 1e30, 1e30]
    mesh.vertices = vertices
    mesh.export(path / "far.stl")
    code, err = uqdrape("drape", "--rings", "3", "--out", "d", cwd=path)
    assert code == 0 and err == "", err
    return path


def test_a_far_stl_vertex_is_one_line(folder):
    code, err = uqdrape("drape", "--geometry", "mesh", "--param", "path=far.stl", "--rings", "3", "--out", "s",
                        cwd=folder)
    assert code == 2
    assert_one_line_error(err, valid=["far.stl", "check units"])
    assert "Warning" not in err


def _noisy(args):
    """A command that warns in this process and in a child interpreter it starts."""
    warnings.warn("parent overflow", RuntimeWarning)
    child = subprocess.run([sys.executable, "-c", "import warnings; warnings.warn('child overflow')"],
                           capture_output=True, text=True, timeout=60)
    sys.stderr.write(child.stderr)
    return 0


def test_warnings_in_a_command_and_its_workers_reach_nobody(monkeypatch, capsys):
    monkeypatch.delenv("PYTHONWARNINGS", raising=False)
    monkeypatch.setattr(sys, "warnoptions", [])
    monkeypatch.setattr(cli, "cmd_validate", _noisy)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert cli.main(["validate", "x.toml"]) == 0
    assert capsys.readouterr().err == "" and seen == []
    assert "PYTHONWARNINGS" not in os.environ  # put back as it was


def test_warnings_are_shown_to_whoever_asks_for_them(monkeypatch, capsys):
    """Under python -W / PYTHONWARNINGS the same command warns: the silence is uqdrape's
    doing, and a user debugging can undo it."""
    monkeypatch.setenv("PYTHONWARNINGS", "default")
    monkeypatch.setattr(sys, "warnoptions", ["default"])
    monkeypatch.setattr(cli, "cmd_validate", _noisy)
    with pytest.warns(RuntimeWarning, match="parent overflow"):
        assert cli.main(["validate", "x.toml"]) == 0
    assert "child overflow" in capsys.readouterr().err


def test_a_card_force_past_the_limit_is_refused_before_it_overflows(folder):
    (folder / "huge.toml").write_text("[shear.positive]\nangle_deg = [0, 30, 60]\nns = [0, 1e300, 1.7e308]\n")
    code, err = uqdrape("drape", "--material", "huge.toml", "--rings", "3", "--out", "h", cwd=folder)
    assert code == 2
    assert_one_line_error(err, file="huge.toml", key="shear.positive", valid=["at most 1e+06 N/m"])


def test_a_card_force_at_the_limit_drapes_in_silence(folder):
    (folder / "stiff.toml").write_text("[shear.positive]\nangle_deg = [0, 30, 60]\nns = [0, 5e5, 1e6]\n")
    code, err = uqdrape("drape", "--material", "stiff.toml", "--rings", "3", "--out", "k", cwd=folder)
    assert (code, err) == (0, "")


@pytest.mark.parametrize("flag, value", [("--reference", "inf"), ("--reference", "nan"), ("--tolerance", "inf")])
def test_a_non_finite_export_flag_is_one_line(folder, flag, value):
    code, err = uqdrape("export", "d.nc", "--to", "vtk", flag, value, "--out", "e", cwd=folder)
    assert code == 2
    assert_one_line_error(err, valid=[flag, "finite"])
    assert not list(folder.glob("e*"))


def test_an_export_at_a_huge_reference_angle_is_silent(folder):
    code, err = uqdrape("export", "d.nc", "--to", "vtk", "--reference", "1e300", "--out", "big", cwd=folder)
    assert (code, err) == (0, "")
