"""Inputs whose size or value would run a command out of memory or into junk are refused
in one line, before the work, naming the size or value and the limit: calibration points,
images and their window, training points, sectors, worker processes; a fibre direction of
nan, a measurement sd of 1e200, a measured shear of 1e300; a mesh's units as a list."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import assert_one_line_error, write_study
from PIL import Image

from uqdrape.calibration.points import MAX_POINTS
from uqdrape.cli import main
from uqdrape.workflow.preflight import WORKERS_PER_CORE


def _points_csv(path, n, sd=None):
    """A fibre-angle CSV of ``n`` set-1 points near 45 deg on a 5 mm grid (an sd column if ``sd``)."""
    rng = np.random.default_rng(0)
    side = int(np.ceil(np.sqrt(n)))
    rows = [f"{5.0 * (k % side)},{5.0 * (k // side)},{45.0 + rng.normal(0.0, 2.0):.3f},1"
            + ("" if sd is None else f",{sd}") for k in range(n)]
    path.write_text("x_mm,y_mm,angle_deg,fibre_set" + ("" if sd is None else ",sd_deg") + "\n"
                    + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def _calibrate(tmp_path, *args):
    return main(["calibrate", *map(str, args), "--out", str(tmp_path / "block.toml")])


def test_more_calibration_points_than_the_limit_are_refused_before_any_fit(tmp_path, capsys):
    path = _points_csv(tmp_path / "many.csv", MAX_POINTS + 1)
    assert _calibrate(tmp_path, path) == 2
    assert_one_line_error(capsys.readouterr().err, file=path, valid=[f"{MAX_POINTS + 1} points", str(MAX_POINTS)])
    assert not (tmp_path / "block.toml").exists()


@pytest.mark.parametrize("args, named", [(["--fibre1-deg", "nan"], "--fibre1-deg"),
                                         (["--fibre1-deg", "1e300"], "--fibre1-deg")])
def test_a_fibre_direction_that_is_no_angle_is_refused(tmp_path, capsys, args, named):
    assert _calibrate(tmp_path, _points_csv(tmp_path / "p.csv", 30), *args) == 2
    assert_one_line_error(capsys.readouterr().err, valid=[named])
    assert not (tmp_path / "block.toml").exists()


@pytest.mark.parametrize("column, value", [("sd_deg", "1e200"), ("x_mm", "1e300")])
def test_a_measurement_sd_or_position_past_physical_sense_is_refused(tmp_path, capsys, column, value):
    path = _points_csv(tmp_path / "p.csv", 30, sd=0.5)
    lines = path.read_text().splitlines()
    cells = lines[5].split(",")
    cells[lines[0].split(",").index(column)] = value
    lines[5] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    assert _calibrate(tmp_path, path) == 2
    assert_one_line_error(capsys.readouterr().err, file=path, valid=["row 6", column])


def test_an_image_of_too_many_pixels_is_refused_before_its_pixels_are_decoded(tmp_path, capsys):
    path = tmp_path / "big.png"
    Image.new("L", (4100, 4100)).save(path)
    assert _calibrate(tmp_path, path, "--mm-per-px", "0.1") == 2
    assert_one_line_error(capsys.readouterr().err, file=path, valid=["4100 x 4100", "4096 x 4096"])


def test_a_window_wider_than_the_image_is_refused(tmp_path, capsys):
    pytest.importorskip("skimage")
    path = tmp_path / "tows.png"
    stripes = (127 + 120 * np.sin(np.arange(64)[None, :] * 0.8)) * np.ones((64, 1))
    Image.fromarray(stripes.astype(np.uint8)).save(path)
    assert _calibrate(tmp_path, path, "--mm-per-px", "0.1", "--window-px", "1e9") == 2
    assert_one_line_error(capsys.readouterr().err, valid=["window_px", "16 px"])


def _part(path, shear="1.5"):
    path.write_text(f"distance_mm,shear_deg,quadrant_sign\n10,{shear},1\n20,2.0,1\n30,3.0,-1\n", encoding="utf-8")
    return path


def test_a_measured_shear_of_1e300_is_refused_not_calibrated_from_the_prior(tmp_path, capsys):
    study = write_study(tmp_path, uncertainty={"zero_angle": {"sd_deg": 2.0}})
    part = _part(tmp_path / "part.csv", "1e300")
    assert main(["calibrate", "--drapes", str(part), "--study", str(study), "--parameter",
                 "uncertainty.zero_angle.sd_deg=0.5:4", "--out", str(tmp_path / "cal.toml")]) == 2
    assert_one_line_error(capsys.readouterr().err, file=part, valid=["row 2", "shear_deg", "90"])


@pytest.mark.parametrize("flag, value, valid", [("--training-points", "1000000000", "from 3 to 1000"),
                                                ("--realizations", "1000000000", "from 3 to 10000"),
                                                ("--measurement-sd", "1e200", "from 0 to 90"),
                                                ("--workers", "1000000", "--workers: workers must be from 1 to")])
def test_a_calibration_from_drapes_of_absurd_size_is_refused_before_any_drape(tmp_path, capsys, flag, value, valid):
    study = write_study(tmp_path, uncertainty={"zero_angle": {"sd_deg": 2.0}})
    assert main(["calibrate", "--drapes", str(_part(tmp_path / "part.csv")), "--study", str(study), "--parameter",
                 "uncertainty.zero_angle.sd_deg=0.5:4", flag, value, "--scheduler", "synchronous",
                 "--out", str(tmp_path / "cal.toml")]) == 2
    assert_one_line_error(capsys.readouterr().err, valid=[flag, valid])
    assert not (tmp_path / "cal.toml").exists()


@pytest.mark.parametrize("workers", ["0", "1000000"])
def test_workers_beyond_a_few_per_core_are_refused_before_spawning(tmp_path, capsys, workers):
    study = write_study(tmp_path)
    assert main(["run", str(study), "--workers", workers, "--no-report"]) == 2
    assert_one_line_error(capsys.readouterr().err, valid=["--workers", f"{WORKERS_PER_CORE} per core"])
    assert not (tmp_path / "tiny").exists()


def test_design_sectors_beyond_the_limit_are_refused_by_validate(tmp_path, capsys):
    study = write_study(tmp_path)
    study.write_text(study.read_text() + '\n[design]\nvariables = "sectors"\nsectors = 1000000000\n'
                                         'force_bounds_N = [0.0, 500.0]\n', encoding="utf-8")
    assert main(["validate", str(study)]) == 2
    assert_one_line_error(capsys.readouterr().err, file=study, key="design.sectors", valid=["37"])


@pytest.mark.parametrize("key, limit", [("max_evaluations", "10001"), ("validation_realizations", "1000001")])
def test_design_sizes_beyond_their_limits_are_refused_by_validate(tmp_path, capsys, key, limit):
    study = write_study(tmp_path)
    study.write_text(study.read_text() + f'\n[design]\nvariables = "force"\nforce_bounds_N = [0.0, 500.0]\n'
                                         f'objective = "p_locked"\n{key} = 1000000000\n', encoding="utf-8")
    assert main(["validate", str(study)]) == 2
    assert_one_line_error(capsys.readouterr().err, file=study, key=f"design.{key}", valid=[limit])


@pytest.mark.parametrize("units", ["[]", "{}", "1"])
def test_mesh_units_of_the_wrong_type_are_one_line(tmp_path, capsys, units):
    import shutil
    from pathlib import Path

    shutil.copy(Path(__file__).parent / "data" / "hemisphere_r50.stl", tmp_path / "dome.stl")
    study = write_study(tmp_path, geometry={"kind": "mesh", "path": "dome.stl", "radius": None})
    study.write_text(study.read_text().replace('path = "dome.stl"', f'path = "dome.stl"\nunits = {units}'))
    assert main(["validate", str(study)]) == 2
    assert_one_line_error(capsys.readouterr().err, file=study, key="geometry.units", valid=["mm", "in"])


@pytest.mark.parametrize("argv, flag", [
    (["drape", "--rings", "2", "--out", "http://127.0.0.1:9/x"], "--out"),
    (["materials", "generic_woven", "--plot", "http://127.0.0.1:9/x.png"], "--plot"),
    (["materials", "derive", "fge106hd", "--out", "s3://bucket/card.toml"], "--out"),
    (["calibrate", "POINTS", "--out", "http://127.0.0.1:9/block.toml"], "--out"),
    (["calibrate", "POINTS", "--out", "block.toml", "--report", "https://127.0.0.1:9/r"], "--report"),
])
def test_a_url_where_a_command_writes_local_files_is_refused_not_folded_into_a_folder(tmp_path, capsys, monkeypatch,
                                                                                        argv, flag):
    monkeypatch.chdir(tmp_path)
    points = str(_points_csv(tmp_path / "p.csv", 30))
    assert main([points if a == "POINTS" else a for a in argv]) == 2
    assert_one_line_error(capsys.readouterr().err, valid=[flag, "://", "give a path"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.csv"]  # no http: or s3: folder


def test_points_spread_over_a_micrometre_fraction_are_refused_before_the_figure(tmp_path, capsys):
    """Coordinates in the wrong unit: the figure's axes overflowed FreeType (a traceback)."""
    path = _points_csv(tmp_path / "p.csv", 30)
    lines = path.read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    path.write_text(lines[0] + "\n" + "".join(f"{float(x) * 1e-7},{float(y) * 1e-7},{a},{s}\n" for x, y, a, s in rows))
    assert _calibrate(tmp_path, path, "--plot") == 2
    assert_one_line_error(capsys.readouterr().err, file=path, valid=["mm of each other", "0.001 mm"])
    assert not any(p.name.startswith("block") for p in tmp_path.iterdir())
