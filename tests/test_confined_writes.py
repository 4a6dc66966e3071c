"""Writes stay in the output (issue 40): a symbolic link planted at a temporary name in a
run folder or a file:// store is replaced, never written through; a study's
``file://`` directory is held to the rule of a path, and fsspec's other spellings of the
local disk (``local://``, chained URLs) are refused; a store URL with nothing after
``://`` and a memory:// store that the run's worker processes cannot write are refused
in one line, before anything is written."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from uqdrape.cli import main
from uqdrape.ensemble.zarrstore import ZarrStore
from uqdrape.files import LOCAL_PROTOCOLS, write_all, write_text_atomic
from uqdrape.study import StudyError, load_study
from uqdrape.workflow import run_report, run_study

from conftest import assert_one_line_error, write_study

VICTIM = "not uqdrape's\n"


@pytest.fixture()
def victim(tmp_path):
    """A file outside every output folder, that no write may change."""
    path = tmp_path / "victim.txt"
    path.write_text(VICTIM)
    return path


def plant(link: Path, to: Path) -> None:
    link.parent.mkdir(parents=True, exist_ok=True)
    link.symlink_to(to)


@pytest.mark.parametrize("name", ["run.part.json", "report/index.part.html", "report/summary.part.json"])
def test_a_link_at_a_temporary_name_of_a_run_folder_is_not_followed(tmp_path, victim, name):
    study = load_study(write_study(tmp_path, study={"realizations": 2}, solver={"mode": "geodesic", "rings": 4}))
    out = run_study(study, scheduler="synchronous", progress=False)
    plant(out / name, victim)
    run_study(study, scheduler="synchronous", progress=False)  # resume: writes run.json
    run_report(out)
    assert victim.read_text() == VICTIM
    assert not (out / name).exists() and not (out / name).is_symlink()
    assert (out / name.replace(".part", "")).is_file()


def test_write_atomic_and_write_all_replace_a_planted_link(tmp_path, victim):
    plant(tmp_path / "out" / "a.part.txt", victim)
    plant(tmp_path / "out" / "b.part.csv", victim)
    plant(tmp_path / "out" / "b.csv", victim)  # the rename replaces a link at the target itself
    write_text_atomic(tmp_path / "out" / "a.txt", "a\n")
    write_all({tmp_path / "out" / "b.csv": lambda tmp: tmp.write_text("b\n")})
    assert victim.read_text() == VICTIM
    assert (tmp_path / "out" / "a.txt").read_text() == "a\n" and (tmp_path / "out" / "b.csv").read_text() == "b\n"
    assert not (tmp_path / "out" / "b.csv").is_symlink()


def test_a_file_store_replaces_links_at_its_part_and_target_names(tmp_path, victim):
    store, folder = tmp_path / "store", tmp_path / "elsewhere"
    folder.mkdir()
    plant(store / "run.json.part", victim)
    plant(store / "rare.json", folder)  # shutil.move would move the part into this folder
    where = ZarrStore(f"file://{store}")
    where.write_manifest({"chunks": []})
    where.write_text("rare.json", "{}\n")
    assert victim.read_text() == VICTIM and not any(folder.iterdir())
    assert (store / "run.json").is_file() and (store / "rare.json").read_text() == "{}\n"


@pytest.mark.parametrize("directory", ["file://../x", "file://results/../../x", "file://", "file:///", "memory://"])
def test_a_file_url_is_held_to_the_rule_of_a_path(tmp_path, monkeypatch, directory):
    monkeypatch.chdir(tmp_path)
    path = write_study(tmp_path, output={"directory": directory})
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert err.value.key == "output.directory"
    assert_one_line_error(str(err.value), file=path, key="output.directory")


@pytest.mark.parametrize("directory", ["local://../x", "local://results/x", "FILE://../x", "simplecache::file://../x",
                                       "dir::file://../x"])
def test_other_spellings_of_the_local_disk_are_refused(tmp_path, monkeypatch, directory):
    """Issue 40: ``local://../x`` (fsspec's alias of file://) escaped the folder that
    ``file://../x`` and ``../x`` are held to, as did a chained URL; each is refused naming
    the valid forms, even where its path would stay inside."""
    monkeypatch.chdir(tmp_path)
    path = write_study(tmp_path, output={"directory": directory})
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key="output.directory", valid=["file:///abs/path"])


def test_the_local_spellings_refused_are_fsspec_s():
    from fsspec.implementations.local import LocalFileSystem

    assert set(LOCAL_PROTOCOLS) == set(LocalFileSystem.protocol)


@pytest.mark.parametrize("out", ["file://", "file:///", "memory://runs/x", "local://{tmp}/store",
                                 "simplecache::file://{tmp}/store"])
def test_run_refuses_a_store_it_cannot_write_in_one_line(tmp_path, monkeypatch, capsys, out):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    study = write_study(tmp_path, study={"realizations": 2}, solver={"mode": "geodesic", "rings": 4})
    out = out.format(tmp=tmp_path)
    assert main(["run", str(study), "--out", out, "--workers", "1", "-q"]) == 2
    assert_one_line_error(capsys.readouterr().err, file=out)
    assert not os.listdir(work) and not (tmp_path / "tiny").exists() and not (tmp_path / "store").exists()


def test_validate_refuses_a_memory_store_in_one_line(tmp_path, capsys):
    study = write_study(tmp_path, output={"directory": "memory://runs/x"})
    assert main(["validate", str(study)]) == 2
    assert_one_line_error(capsys.readouterr().err, file=study, key="output.directory", valid=["memory://"])


@pytest.mark.parametrize("backend, folder, command", [
    ("folder", "chunks", "run"), ("folder", "report", "report"), ("folder", "export", "export"),
    ("file", "report", "report"), ("file", "done", "run"),
])
def test_a_folder_of_a_run_that_is_a_link_is_refused_and_nothing_is_written_through_it(tmp_path, capsys, backend,
                                                                                      folder, command):
    study = write_study(tmp_path, study={"realizations": 2}, solver={"mode": "geodesic", "rings": 4})
    out = tmp_path / "tiny" if backend == "folder" else f"file://{tmp_path}/store"
    assert main(["run", str(study), "--out", str(out), "--scheduler", "synchronous", "-q", "--no-report"]) == 0
    local = Path(str(out).removeprefix("file://"))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    if (local / folder).exists():
        os.rename(local / folder, elsewhere / "kept")
    plant(local / folder, elsewhere)
    before = sorted(p.relative_to(elsewhere) for p in elsewhere.rglob("*"))
    argv = {"run": ["run", str(study), "--out", str(out), "--scheduler", "synchronous", "-q", "--no-resume"],
            "report": ["report", str(out)], "export": ["export", str(out), "--to", "netcdf"]}[command]
    assert main(argv) == 3
    assert_one_line_error(capsys.readouterr().err, file=local / folder, valid=["a symbolic link to a folder"])
    assert sorted(p.relative_to(elsewhere) for p in elsewhere.rglob("*")) == before
