"""Blank-holder design under uncertainty: the [design] section, the optimisers on known
answers (a synthetic drape through the same pipeline), validation, resume, refusals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from uqdrape import design
from uqdrape.drape import draw_in
from uqdrape.workflow import design_outcome, run_design
from uqdrape.cli import main as cli
from uqdrape.study import StudyError, load_study

from conftest import assert_one_line_error, study_text, write_study

STUDIES = Path(__file__).resolve().parents[1] / "studies"

def _sections(realizations=32, rings=4):
    """The base study (``write_study``'s keywords): a R 100 mm hemisphere, a random zero angle."""
    return dict(study={"seed": 7, "realizations": realizations, "chunk_size": 16}, geometry={"radius": 100.0},
                process={"blankholder_force_N": 100.0}, solver={"mode": None, "rings": rings},
                uncertainty={"zero_angle": {"sd_deg": 2.0}})


def write(tmp_path, design_text: str, name="d.toml", **base) -> Path:
    """The base study (``_sections``' keywords) with ``design_text`` as its [design] section
    (TOML text, the input under test); its output folder is tmp_path/out."""
    text = study_text(tmp_path, "d", output={"directory": tmp_path / "out"}, **_sections(**base))
    path = tmp_path / name
    path.write_text(text + "\n[design]\n" + design_text + "\n", encoding="utf-8")
    return path


#: Synthetic optimum: sector forces (N) at which the synthetic quantile is least.
CENTRE = 290.0
#: ... and the friction coefficient (the study's own is 0.2).
FRICTION = 0.2
#: Synthetic draw-in (mm) of realisation r: DRAW_IN_0 - total force / DRAW_IN_RATE + noise_r / 2.
DRAW_IN_0, DRAW_IN_RATE = 30.0, 20.0


def synthetic_drape(study, realizations, force, sectors, friction):
    """A drape stand-in with a known optimum: max |shear| of realisation r is
    30 + ((f_k - CENTRE) / 100)^2 summed over the sector forces f_k
    + ((friction - FRICTION) / 0.05)^2 + noise_r, so every quantile of it, and its CRN
    estimate, is least at f_k = CENTRE, friction = FRICTION (deg). The largest draw-in
    falls with the total force (DRAW_IN_0, DRAW_IN_RATE)."""
    r = np.asarray(realizations)
    n = 1 if sectors is None else len(sectors)
    forces = np.full(n, force / n) if sectors is None else force * np.asarray(sectors)
    noise = np.array([np.random.default_rng([study.seed, int(k)]).normal() for k in r])
    shear = 30.0 + np.sum(((forces - CENTRE) / 100.0) ** 2) + ((friction - FRICTION) / 0.05) ** 2 + 0.5 * noise
    line = np.zeros((4, r.size, 3))
    line[:, :, 1:] = noise[None, :, None]
    return xr.Dataset({
        "any_locked": ("realization", (noise > 1.0).astype(float)),
        "max_abs_shear": ("realization", shear),
        "max_draw_in": ("realization", DRAW_IN_0 - force / DRAW_IN_RATE + 0.5 * noise),
        "line_shear": (("quadrant", "realization", "k"), line),
        "node_locked": (("i", "j"), np.zeros((3, 3))),
        "node_valid": (("i", "j"), np.full((3, 3), float(r.size))),
        "node_x": (("i", "j"), np.zeros((3, 3))),
        "node_y": (("i", "j"), np.zeros((3, 3))),
    }, coords={"realization": r, "quadrant": ["++", "-+", "--", "+-"], "k": [0, 1, 2]})


def run(path, out=None, drape=synthetic_drape):
    study = load_study(path)
    folder = run_design(study, output_dir=out, scheduler="synchronous", progress=False, drape=drape)
    return xr.load_dataset(folder / design.DESIGN_FILE)


def test_uniform_force_finds_the_known_minimum(tmp_path):
    ds = run(write(tmp_path, 'variables = "force"\nforce_bounds_N = [0.0, 1000.0]\n'
                             'objective = "q95_max_abs_shear"\nstatistic = "estimate"\ntolerance_N = 2.0\nmax_evaluations = 30\n'))
    assert abs(float(ds.attrs["optimum"]) - CENTRE) <= 2.0  # xatol of the bounded Brent
    assert int((ds["sample"] == "design").sum()) <= 30
    val = json.loads(ds.attrs["validation"])
    assert val["optimum"]["x"] == [float(ds.attrs["optimum"])]
    assert ds.attrs["validation_seed"] == design.validation_seed(load_study(tmp_path / "d.toml"))
    assert "F = 29" in ds.attrs["summary"]


@pytest.mark.slow
def test_sector_forces_find_the_known_minimum_under_the_budget(tmp_path):
    # 4 sectors, each free in [0, 500] N but together at most 800 N: the constrained optimum
    # is 200 N each (the budget binds, the objective is symmetric in the sectors)
    ds = run(write(tmp_path, 'variables = "sectors"\nsectors = 4\nforce_bounds_N = [0.0, 500.0]\n'
                             'budget_N = 800.0\nobjective = "q95_max_abs_shear"\nstatistic = "estimate"\nmax_evaluations = 60\n'))
    opt = np.asarray(ds.attrs["optimum"])
    assert opt.sum() <= 800.0 + 1e-9
    np.testing.assert_allclose(opt, 200.0, atol=40.0)  # a few DE generations: 40 N stated in the docs
    margin = json.loads(ds.attrs["margin"])
    assert set(margin) == {"design", "validation"}


@pytest.mark.slow
def test_force_and_friction_find_the_known_minimum(tmp_path):
    ds = run(write(tmp_path, 'variables = "force"\nforce_bounds_N = [0.0, 1000.0]\nfriction_bounds = [0.1, 0.4]\n'
                             'objective = "q95_max_abs_shear"\nstatistic = "estimate"\nmax_evaluations = 60\n'))
    force, friction = ds.attrs["optimum"]
    assert abs(force - CENTRE) <= 60.0 and abs(friction - FRICTION) <= 0.03  # a few DE generations
    assert list(ds["variable"].values) == ["force", "friction"]


def test_draw_in_limit_moves_the_optimum_to_the_least_force_that_keeps_it(tmp_path):
    # unconstrained the optimum is CENTRE = 290 N (test above); the synthetic draw-in's 95 %
    # quantile DRAW_IN_0 - F / DRAW_IN_RATE + q95(noise) / 2 falls to the 12 mm limit at F_min
    ds = run(write(tmp_path, 'variables = "force"\nforce_bounds_N = [0.0, 1000.0]\nobjective = "q95_max_abs_shear"\n'
                             'statistic = "estimate"\ntolerance_N = 2.0\nmax_evaluations = 30\nmax_draw_in_mm = 12.0\n'))
    noise = [np.random.default_rng([7, k]).normal() for k in range(32)]
    f_min = DRAW_IN_RATE * (DRAW_IN_0 - 12.0 + 0.5 * np.quantile(noise, 0.95))
    assert f_min > CENTRE + 50
    optimum = float(ds.attrs["optimum"])
    assert f_min <= optimum <= f_min + 2.0  # feasible, within xatol of the limit
    design_sample = ds.isel(evaluation=np.flatnonzero(ds["sample"].values == "design"))
    below = design_sample["total_force"] < f_min
    assert (design_sample["feasible"] == ~below).all()  # the limit is a floor on the force
    assert ds.attrs["max_draw_in_mm"] == 12.0
    assert "Draw-in at the optimum (95 % quantile of the largest, mm)" in ds.attrs["summary"]


def test_a_draw_in_limit_no_design_keeps_gives_the_least_infeasible_design_and_says_so(tmp_path):
    # the synthetic draw-in's 95 % quantile is above 15 mm at every force up to 300 N
    ds = run(write(tmp_path, 'variables = "force"\nforce_bounds_N = [0.0, 300.0]\nobjective = "q95_max_abs_shear"\n'
                             'statistic = "estimate"\ntolerance_N = 2.0\nmax_evaluations = 30\nmax_draw_in_mm = 1.0\n'))
    assert int(ds["feasible"].sum()) == 0
    assert float(ds.attrs["optimum"]) >= 300.0 - 2.0  # the least draw-in: the largest force, to xatol
    assert ds.attrs["summary"].endswith("limit 1 mm on its estimate: BROKEN on the validation sample; "
                                        "no evaluated design keeps it.")


@pytest.mark.slow  # end to end: two design runs and their reports
def test_design_report_shows_the_draw_in_limit(tmp_path, unrasterised):
    from uqdrape.geometry import build
    from uqdrape.report import write_design_report

    text = ('variables = "force"\nforce_bounds_N = [0.0, 1000.0]\nobjective = "q95_max_abs_shear"\n'
            'statistic = "estimate"\ntolerance_N = 2.0\nmax_evaluations = 12\n')
    heights = {}
    for limit in ("", "max_draw_in_mm = 12.0\n"):
        ds = run(write(tmp_path, text + limit), out=tmp_path / f"run{bool(limit)}")
        index = write_design_report(ds, tmp_path / f"report{bool(limit)}", surface=build("hemisphere", radius=100.0))
        record = json.loads((index.parent / "summary.json").read_text())
        assert record["figures"] == ["objective.png", "risk_map.png", "convergence.png"]
        heights[bool(limit)] = unrasterised[-3].get_size_inches()[1]  # objective, risk map, convergence
        page = index.read_text()
        assert ("<th>draw-in limit (mm)</th><td>12 on the estimate" in page) == bool(limit)
        # provenance like every report page: the design run's own wall time
        prov = record["provenance"]
        assert prov["wall_time_s"] == ds.attrs["wall_time_s"] >= 0 and prov["uqdrape_version"] == "0.1.0"
        assert f"Report of {prov['date']}, uqdrape 0.1.0" in page and f"{prov['wall_time_s']:.1f} s." in page
    assert heights[True] > 1.5 * heights[False]  # the draw-in panel under the objective's


def test_draw_in_is_zero_on_a_plate_and_the_arc_deficit_on_a_hemisphere():
    """Radial draw-in of the held edge: a plate keeps the flat blank (0); on a hemisphere of
    radius R draped geodesically from the pole the arm node (n, 0) sits at plan radius
    R sin(n a), a = 2 asin(s / 2R) per chord, so it is drawn in by n s - R sin(n a); every
    edge node of a convex mould is drawn in."""
    from uqdrape.drape import drape
    from uqdrape.geometry import build

    n, s, R = 6, 5.0, 100.0
    plate = drape(build("plate"), s, n, orientation=[0.0, 30.0])
    assert float(abs(draw_in(plate)).max()) < 1e-12
    dome = drape(build("hemisphere", radius=R), s, n)
    d = draw_in(dome).isel(realization=0)
    a = 2 * np.arcsin(s / (2 * R))
    np.testing.assert_allclose(float(d.sel(i=n, j=0)), n * s - R * np.sin(n * a), rtol=1e-9)
    edge = d.where(np.isfinite(d), drop=True)
    assert int(np.isfinite(d).sum()) == 8 * n and float(edge.min()) > 0
    assert bool(d.sel(i=slice(-n + 1, n - 1), j=slice(-n + 1, n - 1)).isnull().all())


@pytest.mark.slow  # end to end: a design run, killed, resumed
def test_interrupted_design_resumes_to_the_same_result(tmp_path):
    text = ('variables = "force"\nforce_bounds_N = [0.0, 1000.0]\nobjective = "q95_max_abs_shear"\nstatistic = "estimate"\n'
            'tolerance_N = 2.0\nmax_evaluations = 30\n')
    clean = run(write(tmp_path, text), out=tmp_path / "clean")
    calls = []

    def dying(*args):
        calls.append(1)
        if len(calls) > 12:  # killed after 6 designs (2 chunks each)
            raise KeyboardInterrupt
        return synthetic_drape(*args)

    path = write(tmp_path, text)
    with pytest.raises(KeyboardInterrupt):
        run(path, out=tmp_path / "resumed", drape=dying)
    assert len(list((tmp_path / "resumed" / design.EVALUATIONS).glob("*.nc"))) == 6
    resumed = run(path, out=tmp_path / "resumed")
    for name in ("x", "objective", "q95_max_abs_shear", "q95_max_abs_shear_upper", "key"):
        np.testing.assert_array_equal(resumed[name].values, clean[name].values)
    assert resumed.attrs["summary"] == clean.attrs["summary"]
    # what each run did, as `uqdrape design` says it: the resume drew only what the first had not
    n = int(clean.attrs["designs_draped"])
    assert design_outcome(tmp_path / "clean") == f"designs written to {tmp_path / 'clean'}: {n} designs draped"
    assert design_outcome(tmp_path / "resumed") == (f"resumed: 6 of {n} designs kept from evaluations/, {n - 6} "
                                                    f"draped; designs in {tmp_path / 'resumed'}")


FORCE = 'variables = "force"\nforce_bounds_N = [0.0, 100.0]\nobjective = "p_locked"'


# (design text, the key, its value as written, what the message must offer as valid)
@pytest.mark.parametrize("text, key, value, valid", [
    ('variables = "force"\nforce_bounds_N = [500.0, 100.0]\nobjective = "p_locked"',
     "design.force_bounds_N", "[500.0, 100.0]", ["two numbers [lo, hi] with 0 <= lo < hi", "(N, total force)"]),
    ('variables = "sectors"\nsectors = 4\nforce_bounds_N = [100.0, 500.0]\nbudget_N = 300.0\nobjective = "p_locked"',
     "design.budget_N", "300.0", [">= the smallest total force the bounds allow", "4 x 100 = 400 N"]),
    ('variables = "force"\nforce_bounds_N = [0.0, 100.0]\nobjective = "p_wrinkle"',
     "design.objective", '"p_wrinkle"', ['"p_locked"', '"q95_max_abs_shear"', '"abs_mean_asymmetry"', '"q95_max_draw_in"']),
    ('variables = "sectors"\nsectors = 1\nforce_bounds_N = [0.0, 100.0]\nobjective = "p_locked"',
     "design.sectors", "1", ["2 <= sectors < 37"]),
    (FORCE + "\nmax_draw_in_mm = -5.0", "design.max_draw_in_mm", "-5.0", ["number > 0"]),
    (FORCE + '\nmax_draw_in_mm = "20 mm"', "design.max_draw_in_mm", '"20 mm"', ["number > 0"]),
    (FORCE + "\nmax_draw_in_mm = 20.0", "study.realizations", "32", ["at least 72", 'statistic = "estimate"']),
])
def test_bad_design_is_refused_in_one_line(tmp_path, capsys, text, key, value, valid):
    path = write(tmp_path, text)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert str(err.value).startswith(f"{path}: ")
    assert_one_line_error(str(err.value), file=path, key=key, value=value, valid=valid)
    assert cli(["validate", str(path)]) == 2
    assert_one_line_error(capsys.readouterr().err, file=path, key=key, value=value, valid=valid)


def test_design_round_trips_through_the_study_dict():
    from uqdrape.study import from_dict

    for path in STUDIES.glob("design-*.toml"):
        study = load_study(path)
        assert from_dict(study.to_dict(), path).design == study.design


@pytest.mark.slow
def test_symmetric_woven_on_the_hemisphere_gets_equal_sector_forces(tmp_path):
    """Real drapes: a woven fabric on a hemisphere is symmetric under a quarter turn, so
    the 4-sector design of least 95 % quantile of max |shear| at a fixed budget is the
    equal split (to the DE tolerance, 40 N of 800 N)."""
    path = write(tmp_path, 'variables = "sectors"\nsectors = 4\nforce_bounds_N = [0.0, 400.0]\nbudget_N = 800.0\n'
                           'objective = "q95_max_abs_shear"\nstatistic = "estimate"\nmax_evaluations = 48',
                 "h.toml", realizations=16, rings=8)
    ds = xr.load_dataset(run_design(load_study(path), scheduler="synchronous", progress=False)
                         / design.DESIGN_FILE)
    opt = np.asarray(ds.attrs["optimum"])
    np.testing.assert_allclose(opt, opt.mean(), atol=40.0)


def test_design_command_needs_a_design_section(tmp_path, capsys):
    path = write_study(tmp_path, "plain", **_sections())
    assert cli(["design", str(path)]) == 2
    assert_one_line_error(capsys.readouterr().err, file=path, key="[design]", valid=["uqdrape run"])


def test_run_of_a_design_study_refuses_ensemble_options(tmp_path, capsys):
    path = write(tmp_path, FORCE)
    assert cli(["run", str(path), "--method", "morris"]) == 2
    assert_one_line_error(capsys.readouterr().err, file=path, key="[design]",
                          valid=["--method", "--chunk-size", "--no-resume", "do not apply"])
