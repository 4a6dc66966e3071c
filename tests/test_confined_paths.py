"""Files are data: a path read from a file names a file in that file's folder or below,
a study's relative output folder stays inside the current folder, and an error about a
file that is not what it should be does not echo the file (issue 26)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from conftest import assert_one_line_error, write_study
from uqdrape.files import inside
from uqdrape.material import load_material
from uqdrape.study import StudyError, load_study

#: The text of a file nobody meant uqdrape to show (stands in for /etc/passwd).
SECRET = "s3cr3t:x:0:0:line"


@pytest.mark.parametrize("name, ok", [
    ("a.csv", True), ("sub/a.csv", True), ("sub/../a.csv", True), ("./a.csv", True),
    ("../a.csv", False), ("sub/../../a.csv", False), ("/etc/passwd", False), ("a\0b.csv", False),
    ("../../../../etc/passwd", False),
])
def test_inside_reads_the_name_as_written(name, ok):
    assert inside(name) is ok


@pytest.fixture()
def secret_outside(tmp_path):
    """tmp_path/secret.csv (outside) and the folder tmp_path/inner that names it."""
    (tmp_path / "secret.csv").write_text(SECRET + "\n")
    inner = tmp_path / "inner"
    inner.mkdir()
    return inner


@pytest.mark.parametrize("target", ["../secret.csv", "{abs}", "../../../../../../../../etc/passwd"])
def test_a_card_naming_a_file_outside_its_folder_is_refused(secret_outside, target):
    target = target.format(abs=secret_outside.parent / "secret.csv")
    card = secret_outside / "card.toml"
    card.write_text(f'[shear]\ncsv = "{target}"\n')
    with pytest.raises(ValueError) as err:
        load_material(card)
    assert_one_line_error(str(err.value), file=card, key="shear.csv", valid=["'..' are not followed"])
    assert "s3cr3t" not in str(err.value)


def test_a_card_csv_that_is_not_a_curve_csv_is_not_echoed(tmp_path):
    (tmp_path / "notes.csv").write_text(SECRET + "\n1,2\n")
    card = tmp_path / "card.toml"
    card.write_text('[shear]\ncsv = "notes.csv"\n')
    for source in (card, tmp_path / "notes.csv"):
        with pytest.raises(ValueError) as err:
            load_material(source)
        assert_one_line_error(str(err.value), file="notes.csv", valid=["angle_deg,ns_positive"])
        assert "s3cr3t" not in str(err.value)


def test_a_card_csv_that_is_not_text_names_the_file(tmp_path):
    (tmp_path / "c.csv").write_bytes(b"angle_deg,ns_positive\n0,\xff\xfe\x00\n")
    (tmp_path / "card.toml").write_text('[shear]\ncsv = "c.csv"\n')
    with pytest.raises(ValueError) as err:
        load_material(tmp_path / "card.toml")
    assert_one_line_error(str(err.value), file=tmp_path / "c.csv", valid=["UTF-8"])


def test_a_long_bad_cell_is_named_not_quoted(tmp_path):
    (tmp_path / "c.csv").write_text("angle_deg,ns_positive\n0,0\n10," + "z" * 5000 + "\n")
    with pytest.raises(ValueError) as err:
        load_material(tmp_path / "c.csv")
    assert_one_line_error(str(err.value), file="c.csv", valid=["data row 3, column ns_positive", "expected a number"])
    assert "zz" not in str(err.value)


@pytest.mark.parametrize("sections, key", [
    ({"fabric": {"material": "../secret.csv"}}, "fabric.material"),
    ({"report": {"experimental_csv": "../secret.csv"}}, "report.experimental_csv"),
    ({"geometry": {"kind": "mesh", "path": "../secret.stl", "radius": None}}, "geometry.path"),
])
def test_a_study_naming_a_file_outside_its_folder_is_refused(secret_outside, sections, key):
    (secret_outside.parent / "secret.stl").write_text("solid x\nendsolid x\n")
    path = write_study(secret_outside, **sections)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert err.value.key == key
    assert_one_line_error(str(err.value), file=path, key=key, valid=[str(secret_outside), "'..'"])
    assert "s3cr3t" not in str(err.value)


def test_an_experimental_csv_without_its_header_is_not_echoed(tmp_path):
    (tmp_path / "m.csv").write_text(SECRET + "\n1,2,3\n")
    path = write_study(tmp_path, report={"experimental_csv": "m.csv"})
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key="report.experimental_csv",
                          valid=["distance_mm", "quadrant_sign"])
    assert "s3cr3t" not in str(err.value)


@pytest.mark.parametrize("data, valid", [
    (b"distance_mm,shear_deg,quadrant_sign\n1,\xff,1\n", "not UTF-8"),
    (b"distance_mm,shear_deg,quadrant_sign\n1," + b"9" * 200_000 + b",1\n", "not a CSV"),
])
def test_an_experimental_csv_that_is_not_text_or_csv_is_one_line(tmp_path, data, valid):
    (tmp_path / "m.csv").write_bytes(data)
    path = write_study(tmp_path, report={"experimental_csv": "m.csv"})
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file="m.csv", key="report.experimental_csv", valid=[valid])


@pytest.mark.parametrize("directory, ok", [
    ("results/x", True), ("results/../x", True), ("{abs}", True), ("file://results/x", True),
    ("../x", False), ("results/../../x", False), ("../../../../../escaped", False), ("a\0b", False),
])
def test_a_relative_output_folder_stays_in_the_current_folder(tmp_path, monkeypatch, directory, ok):
    monkeypatch.chdir(tmp_path)
    directory = directory.format(abs=tmp_path.parent / "elsewhere")
    path = write_study(tmp_path, output={"directory": directory})
    if ok:
        assert str(load_study(path).output_dir) == directory
        return
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert err.value.key == "output.directory"
    assert_one_line_error(str(err.value), file=path, key="output.directory")


def test_out_on_the_command_line_may_leave_the_current_folder(tmp_path):
    """What the user types is theirs: --out ../elsewhere is written where it says."""
    work = tmp_path / "work"
    work.mkdir()
    study = write_study(tmp_path, output={"directory": "results/tiny"}, study={"realizations": 2})
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    done = subprocess.run([sys.executable, "-m", "uqdrape.cli", "-q", "run", str(study), "--out", "../elsewhere",
                           "--scheduler", "synchronous", "--no-report"],
                          cwd=work, capture_output=True, text=True, timeout=240, env=env)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "elsewhere" / "run.json").is_file() and not (work / "results").exists()
