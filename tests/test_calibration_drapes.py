"""Calibration from measured drapes (issue 25): the GP emulator, the shear at measured points,
the truth recovery on synthetic parts made by uqdrape, the command and its errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import uqdrape.material
from conftest import assert_one_line_error, write_study
from uqdrape.calibration.emulator import Emulator, latin_hypercube
from uqdrape.calibration.parameters import Parameter
from uqdrape.cli import main
from uqdrape.stats import shear_at_points
from uqdrape.study import load_study
from uqdrape.workflow.calibrate import calibrate_parts, synthetic_parts

pytest.importorskip("sklearn")
pytest.importorskip("emcee")

SD_KEY = "uncertainty.zero_angle.sd_deg"
#: A small energy drape whose line shear moves with the zero-angle sd: 6 rings on a 50 mm dome.
SMALL = dict(study={"realizations": 16, "chunk_size": 16}, fabric={"material": "ebxhd936_like"},
             process={"blankholder_force_N": 150.0, "friction": 0.2}, solver={"mode": "energy", "rings": 6},
             uncertainty={"zero_angle": {"mean_deg": 0.0, "sd_deg": 3.0, "correlation": "iid"}})
DISTANCES = [10.0, 20.0, 30.0, 40.0]


def test_the_emulator_is_scikit_learns_gp_prediction():
    """The vectorised predictive equations are the fitted GPs' own (mean and variance)."""
    x = latin_hypercube([0.0, 10.0], [1.0, 30.0], 15, seed=1)
    y = np.column_stack([np.sin(3 * x[:, 0]) + 0.1 * x[:, 1], x[:, 0] ** 2])
    emu = Emulator(x, y, np.full(y.shape, 1e-4), [0.0, 10.0], [1.0, 30.0])
    at = latin_hypercube([0.0, 10.0], [1.0, 30.0], 7, seed=2)
    mean, var = emu.predict(at)
    unit = (at - emu.lower) / (emu.upper - emu.lower)
    for col, gp in enumerate(emu.gps):
        m, s = gp.predict(unit, return_std=True)
        np.testing.assert_allclose(mean[:, col], emu.offset[col] + emu.scale[col] * m, rtol=0, atol=1e-9)
        np.testing.assert_allclose(var[:, col], (emu.scale[col] * s) ** 2, rtol=0, atol=1e-9)


def test_shear_at_a_node_distance_is_that_nodes_shear(tmp_path):
    """Read at a node's own line distance, the shear is the node's; the copies are the two lines of a sign."""
    from uqdrape.drape import max_shear_lines
    from uqdrape.ensemble import drape_inputs, sampled_inputs

    study = load_study(write_study(tmp_path, **SMALL))
    r = np.arange(3)
    ds = drape_inputs(study, r, sampled_inputs(study, r))
    lines = max_shear_lines(ds)
    k = 4
    d = lines["distance"].sel(quadrant="--", k=k).values[1]
    out = shear_at_points(ds.isel(realization=[1]), [d], [1.0])
    assert out[1, 0, 0] == pytest.approx(float(lines["shear"].sel(quadrant="--", k=k).values[1]), abs=1e-9)
    far = shear_at_points(ds, [1e4], [-1.0])
    assert np.isnan(far).all()


def test_synthetic_parts_cover_the_truth_and_four_parts_narrow_it(tmp_path):
    """Parts made by uqdrape at zero-angle sd 3 deg: the 90 % posterior interval of the sd
    covers 3 from one part and from four, and four parts give a narrower one."""
    path = write_study(tmp_path, **SMALL)
    parts = synthetic_parts(path, {SD_KEY: 3.0}, 4, DISTANCES, seed=11, measurement_sd=0.02)
    param = Parameter(SD_KEY, 0.5, 8.0)
    widths = []
    for n in (1, 4):
        cal = calibrate_parts(path, parts[:n], [param], measurement_sd=0.02, scheduler="synchronous", steps=1000)
        lo, hi = cal.interval(param)
        print(f"{n} part(s): sd 90 % interval [{lo:.3f}, {hi:.3f}], median {np.median(cal.posterior.samples[SD_KEY]):.3f}")
        assert lo < 3.0 < hi
        widths.append(hi - lo)
    assert widths[1] < widths[0]


def test_calibrate_drapes_command_writes_the_study_the_sample_and_the_report(tmp_path, capsys, unrasterised):
    study = write_study(tmp_path, **SMALL)
    parts = synthetic_parts(study, {SD_KEY: 3.0}, 2, DISTANCES[:2], seed=5, measurement_sd=0.02)
    csvs = []
    for k, p in enumerate(parts):
        csv = tmp_path / f"p{k}.csv"
        csv.write_text("distance_mm,shear_deg,quadrant_sign\n" + "".join(
            f"{d},{s:.17g},{q:+.0f}\n" for d, s, q in zip(p.distance_mm, p.shear_deg, p.quadrant_sign)))
        csvs.append(str(csv))
    out = tmp_path / "calibrated.toml"
    assert main(["calibrate", "--drapes", *csvs, "--study", str(study), "--parameter", f"{SD_KEY}=0.5:8",
                 "--training-points", "6", "--realizations", "8", "--measurement-sd", "0.02", "--scheduler", "synchronous",
                 "--out", str(out), "--report", str(tmp_path / "report"), "-q"]) == 0
    said = capsys.readouterr().out
    calibrated = load_study(out)
    assert calibrated.name == "tiny-calibrated"
    sample = xr.load_dataset(tmp_path / "calibrated-posterior.nc")
    median = float(np.median(sample["posterior"].sel(parameter=SD_KEY)))
    assert calibrated.uncertainty.fields["zero_angle"].params["sd_deg"] == float(f"{median:.4g}")
    assert sample.sizes["training_point"] == 9 and sample.sizes["part"] == 2  # 6, then 3 from the posterior
    page = (tmp_path / "report" / "index.html").read_text()
    assert "posterior.png" in page and "predictive.png" in page
    assert "% of the measured points inside the 90 % band" in said


@pytest.mark.parametrize("args, key, valid", [
    (["--parameter", "process.nope=0:1"], "process.nope", "KEY=LOW:HIGH"),
    (["--parameter", f"{SD_KEY}=5:1"], SD_KEY, "LOW < HIGH"),
    (["--parameter", f"{SD_KEY}=-1:4"], SD_KEY, "sd_deg"),
    ([], None, "--parameter: a calibration from drapes needs at least one parameter KEY=LOW:HIGH"),
    (["--parameter", f"{SD_KEY}=1:4", "--posterior"], None, "--posterior belong(s) to a calibration from POINTS"),
    (["--parameter", "fabric.imbalance_Nm=2:50"], "fabric.imbalance_Nm", "set in the study file first"),
])
def test_calibrate_drapes_bad_parameters_are_one_line(tmp_path, capsys, args, key, valid):
    study = write_study(tmp_path, **SMALL)
    part = tmp_path / "p.csv"
    part.write_text("distance_mm,shear_deg,quadrant_sign\n10,1.2,1\n")
    out = tmp_path / "c.toml"
    assert main(["calibrate", "--drapes", str(part), "--study", str(study), *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert_one_line_error(err, key=key, valid=[valid])
    assert not out.exists()


def test_a_part_measured_twice_at_one_point_is_refused(tmp_path, capsys):
    study = write_study(tmp_path, **SMALL)
    part = tmp_path / "twice.csv"
    part.write_text("distance_mm,shear_deg,quadrant_sign\n10,1.2,1\n10,1.3,1\n")
    assert main(["calibrate", "--drapes", str(part), "--study", str(study), "--parameter", f"{SD_KEY}=1:4",
                 "--out", str(tmp_path / "c.toml")]) == 2
    assert_one_line_error(capsys.readouterr().err, file="twice.csv", valid=["measured twice"])


def test_a_calibrated_study_that_would_not_find_its_files_is_refused_before_any_drape(tmp_path, capsys):
    """A study naming its card relative to itself, --out in another folder: one line, no drape, no file."""
    (tmp_path / "cards").mkdir()
    card = Path(uqdrape.material.__file__).parent / "cards" / "ebxhd936_like.toml"
    (tmp_path / "cards" / "my.toml").write_text(card.read_text())
    study = write_study(tmp_path, **{**SMALL, "fabric": {"material": "cards/my.toml"}})
    part = tmp_path / "p.csv"
    part.write_text("distance_mm,shear_deg,quadrant_sign\n10,1.2,1\n")
    out = tmp_path / "elsewhere" / "c.toml"
    assert main(["calibrate", "--drapes", str(part), "--study", str(study), "--parameter", f"{SD_KEY}=1:4",
                 "--out", str(out)]) == 2
    assert_one_line_error(capsys.readouterr().err, key="fabric.material", valid=["write it beside", "tiny.toml"])
    assert list((tmp_path / "elsewhere").iterdir()) == []


def test_the_card_imbalance_is_a_parameter_once_the_study_sets_it(tmp_path):
    from uqdrape.calibration.parameters import parse_parameters
    from uqdrape.workflow.calibrate import study_at

    path = write_study(tmp_path, **{**SMALL, "fabric": {"material": "ebxhd936_like", "imbalance_Nm": 20.0}})
    assert parse_parameters(["fabric.imbalance_Nm=2:50"], load_study(path)) == [Parameter("fabric.imbalance_Nm", 2.0, 50.0)]
    assert study_at(path, {"fabric.imbalance_Nm": 7.5}).fabric.card().name == "ebxhd936_like (dN30 = 7.5 N/m)"
