"""The same physical limits whatever the entry point, errors that carry their key, and
checks that run where the files are actually written: a single drape's flags, a random
field's reach, argument errors blamed on the right study key, the preflight on the
folder a run writes, a UTF-16 study end to end."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import assert_one_line_error, write_study
from uqdrape.cli import main as cli
from uqdrape.errors import ParameterError
from uqdrape.material import load_material
from uqdrape.study import StudyError, load_study
from uqdrape.workflow import check_drape_inputs, validate_study


@pytest.mark.parametrize("flags, named, valid", [
    (["--blankholder-force", "1e12"], "--blankholder-force", "[0, 1e+06] N"),
    (["--friction", "1e9"], "--friction", "[0, 2]"),
    (["--rings", "100000"], "--rings", "[1, 1000]"),
    (["--spacing", "0"], "--spacing", "[0.01, 1000) mm"),
    (["--spacing", "1e-6"], "--spacing", "[0.01, 1000) mm"),
    (["--pre-shear", "60", "--skew", "40"], "--pre-shear and --skew", "(-90, 90)"),
    (["--tolerance", "1e9"], "--tolerance", "(0, 1]"),
    (["--pre-shear", "50", "--material", "generic_woven"], "--pre-shear", "locking angle +50 deg"),
])
def test_a_drape_flag_outside_a_studys_range_is_refused_before_draping(tmp_path, capsys, flags, named, valid):
    assert cli(["drape", *flags, "--out", str(tmp_path / "d" / "x")]) == 2
    err = capsys.readouterr().err
    assert_one_line_error(err, valid=[named, valid])
    assert not (tmp_path / "d").exists()


def test_the_drape_limits_are_the_studys(tmp_path):
    """A force a study refuses is refused by the drape command's check with the same range."""
    path = write_study(tmp_path, process={"blankholder_force_N": 2e6})
    with pytest.raises(StudyError) as study:
        load_study(path)
    with pytest.raises(ParameterError) as drape:
        check_drape_inputs(5.0, 4, {"blankholder_force": 2e6})
    assert drape.value.names == ("blankholder_force",) and study.value.key == "process.blankholder_force_N"
    assert "[0, 1e+06] N" in str(drape.value) and "[0, 1e+06] N" in str(study.value)


def test_a_drape_whose_picture_fails_leaves_no_file(tmp_path, monkeypatch, capsys):
    from uqdrape.workflow import single_shot as commands

    def broken(ds, path, **kwargs):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(commands, "plot_lines", broken)
    assert cli(["drape", "--rings", "3", "--out", str(tmp_path / "d" / "x")]) == 3
    assert_one_line_error(capsys.readouterr().err, valid=["x-lines"])
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == []  # neither the .nc nor the net picture


@pytest.mark.parametrize("field, key, valid", [
    ({"zero_angle": {"sd_deg": 30.0}}, "uncertainty.zero_angle.sd_deg", ["210", "(-90, 90)"]),
    ({"zero_angle": {"mean_deg": 89.0, "sd_deg": 1.0}}, "uncertainty.zero_angle.sd_deg", ["96", "(-90, 90)"]),
    ({"spacing": {"cv": 0.2}}, "uncertainty.spacing.cv", ["< 0.143"]),
])
def test_a_field_reaching_past_its_physical_range_is_refused(tmp_path, field, key, valid):
    path = write_study(tmp_path, uncertainty=field)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert err.value.key == key
    assert_one_line_error(str(err.value), file=path, key=key, valid=valid)


@pytest.mark.parametrize("sections, key, valid", [
    ({"fabric": {"spacing_mm": 1e-6}}, "fabric.spacing_mm", ["0.01 <= spacing_mm < 1000"]),
    ({"solver": {"tolerance_deg": 1e9}}, "solver.tolerance_deg", ["(0, 1] degrees"]),
    ({"fabric": {"orientation_deg": 400.0}}, "fabric.orientation_deg", ["[-360, 360] degrees"]),
    ({"uncertainty": {"orientation": {"dist": "normal", "mean": 0.0, "sd": 1e6}}}, "uncertainty.orientation",
     ["[-360, 360] degrees"]),
])
def test_absurd_spacing_tolerance_and_orientation_are_refused_as_the_drape_command_refuses_them(
        tmp_path, sections, key, valid):
    path = write_study(tmp_path, **sections)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key=key, valid=valid)


def test_a_card_with_no_shear_resistance_is_refused_and_one_that_softens_is_kept(tmp_path):
    """N_s = 0 everywhere cannot steer an energy drape; a falling N_s (measured softening)
    keeps W monotone and is a valid card."""
    zero, soft = tmp_path / "zero.csv", tmp_path / "soft.csv"
    zero.write_text("angle_deg,ns_positive\n0,0\n20,0\n50,0\n")
    soft.write_text("angle_deg,ns_positive\n0,0\n10,5\n20,3\n50,20\n")
    with pytest.raises(ValueError) as err:
        load_material(str(zero))
    assert_one_line_error(str(err.value), file=zero, valid=["N_s is 0 at every angle"])
    card = load_material(str(soft))
    w = card.energy_density(np.deg2rad(np.arange(0.0, 50.0, 0.5)))
    assert np.all(np.diff(w) > 0)


@pytest.mark.parametrize("sections, key, valid", [
    ({"fabric": {"pre_shear_deg": 89.9}}, "fabric.pre_shear_deg", ["locking angle +50 deg"]),
    ({"fabric": {"pre_shear_deg": -50.0}}, "fabric.pre_shear_deg", ["locking angle -50 deg"]),
    ({"uncertainty": {"pre_shear": {"dist": "normal", "mean": 10.0, "sd": 8.0}}}, "uncertainty.pre_shear",
     ["pre-shear of 66.28 deg", "locking angle +50 deg"]),
])
def test_a_blank_pre_sheared_to_its_locking_angle_is_refused(tmp_path, sections, key, valid):
    """generic_woven locks at +/-50 deg: a blank sheared that far is locked before forming
    (mean + 7 sd = 66.28 deg for the factor)."""
    path = write_study(tmp_path, **sections)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key=key, valid=valid)


def test_a_skew_past_locking_is_drawn_but_a_net_mostly_off_the_mould_is_a_warning(tmp_path, capsys):
    """A skew is a choice of the drape (the thesis's Fig 5.5 goes past locking), so 89.9 deg
    is accepted, but 40 % of its 81 nodes cannot be placed: validate and run say so on stderr
    (within the failure budget), and --quiet says nothing."""
    path = write_study(tmp_path, fabric={"skew_deg": 89.9})
    assert cli(["validate", str(path)]) == 0
    err = capsys.readouterr().err
    assert_one_line_error(err, valid=["tiny: warning: 40% of the nodes of realisation 0 cannot be placed",
                                      "failure_budget = 0.5", "NaN"])
    assert cli(["run", str(path), "--scheduler", "synchronous", "--no-report", "-q"]) == 0
    assert capsys.readouterr().err == ""
    assert load_study(path).fabric.skew_deg == 89.9


@pytest.mark.parametrize("sections, key", [
    ({"geometry": {"radius": -5.0}}, "geometry.radius"),
    ({"uncertainty": {"friction": {"dist": "uniform", "bounds": [0.3, 0.1]}}}, "uncertainty.friction.bounds"),
    ({"uncertainty": {"zero_angle": {"sd_deg": 1.0, "correlation": "exponential"}}},
     "uncertainty.zero_angle.length_mm"),
])
def test_an_argument_error_is_blamed_on_its_study_key_from_the_names_it_carries(tmp_path, sections, key):
    with pytest.raises(StudyError) as err:
        load_study(write_study(tmp_path, **sections))
    assert err.value.key == key, str(err.value)


def test_validate_checks_the_net_placement_and_blames_the_rings(tmp_path, capsys):
    path = write_study(tmp_path, solver={"rings": 40})  # 400 mm of net on a 50 mm dome
    load_study(path)  # the file itself is valid ...
    with pytest.raises(StudyError) as err:  # ... the preflight is not
        validate_study(path)
    assert err.value.key == "solver.rings"
    assert_one_line_error(str(err.value), file=path, key="solver.rings", value="40",
                          valid=["cannot be placed", "failure_budget = 0.5"])


def test_run_checks_the_folder_it_writes_not_the_studys(tmp_path, capsys):
    blocker = tmp_path / "blocker"
    blocker.write_text("a file")
    path = write_study(tmp_path)
    assert cli(["run", str(path), "--out", str(blocker / "run"), "--scheduler", "synchronous", "-q"]) == 2
    assert_one_line_error(capsys.readouterr().err, file=path, key="output.directory", valid=["is a file"])


def test_a_utf16_study_runs_end_to_end(tmp_path, capsys):
    path = write_study(tmp_path, study={"realizations": 2})
    path.write_bytes(path.read_text(encoding="utf-8").encode("utf-16"))
    assert cli(["run", str(path), "--scheduler", "synchronous", "-q", "--no-report"]) == 0
    from uqdrape.ensemble import open_ensemble

    with open_ensemble(tmp_path / "tiny") as ds:
        assert ds.attrs["study_toml"].startswith("[study]") and ds.sizes["realization"] == 2


def test_the_resume_identity_ignores_where_the_run_folder_is(tmp_path):
    from uqdrape.study import identity

    study = load_study(write_study(tmp_path))
    moved = dataclasses.replace(study, output_dir=tmp_path / "elsewhere", chunk_size=1)
    assert identity(study.to_dict()) == identity(moved.to_dict())
    assert identity(study.to_dict()) != identity(dataclasses.replace(study, seed=4).to_dict())
