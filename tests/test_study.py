"""Study files: shipped studies validate, defaults, sweeps, and keyed error messages."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from uqdrape.cli import main as cli
from uqdrape.stats import SENSITIVITY_QOIS as QOIS
from uqdrape.study import SENSITIVITY_METHODS, StudyError, from_dict, load_study

from conftest import assert_one_line_error, study_text

STUDIES = Path(__file__).resolve().parents[1] / "studies"

#: A valid study as text: the malformed studies below are edits of it.
BASE = study_text(".", "t", study={"seed": 1, "realizations": 8, "chunk_size": None}, geometry={"radius": 100.0},
                  process={"blankholder_force_N": 100.0}, solver={"mode": None}, output=None)


def write(tmp_path, text, name="bad.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def edit(old, new):
    assert BASE.count(old) == 1
    return BASE.replace(old, new)


def force(value, extra=""):
    return edit("blankholder_force_N = 100.0", f"blankholder_force_N = {value}{extra}")


# ---------------------------------------------------------------- shipped studies


def test_every_shipped_study_validates():
    files = sorted(STUDIES.glob("*.toml"))
    assert len(files) >= 5
    for f in files:
        study = load_study(f)
        assert study.name == f.stem
        assert study.path == f


def test_shipped_studies_hold_the_thesis_settings():
    z = load_study(STUDIES / "nosecone-zero-angle.toml")
    assert (z.geometry.kind, z.fabric.material, z.solver.mode) == ("nose_cone", "ebxhd936_like", "energy")
    assert (z.realizations, z.solver.rings, z.fabric.spacing_mm, z.force_levels) == (127, 30, 5.0, (126.0,))
    f = z.uncertainty.fields["zero_angle"]
    assert f.params == {"mean_deg": 0.0, "sd_deg": 5.0} and f.correlation == "iid"

    sweep = load_study(STUDIES / "nosecone-blankholder-sweep.toml")
    assert sweep.force_levels == (0.0, 126.0, 252.0, 378.0) and sweep.is_sweep
    assert sweep.uncertainty.fields["spacing"].params == {"cv": 0.001} and sweep.realizations == 64

    plate = load_study(STUDIES / "plate-spacing.toml")
    corr = load_study(STUDIES / "plate-correlated-spacing.toml")
    assert plate.fabric == corr.fabric and plate.solver == corr.solver
    assert plate.uncertainty.fields["spacing"].length_mm is None
    assert corr.uncertainty.fields["spacing"].correlation == "squared_exponential"
    assert corr.uncertainty.fields["spacing"].length_mm == (100.0, 100.0)

    hemi = load_study(STUDIES / "hemisphere-skew.toml")
    skew = hemi.uncertainty.factors["skew"]
    assert skew.dist == "uniform" and skew.ppf([0.0, 0.5, 1.0]).tolist() == pytest.approx([0, 27.5, 55], abs=1e-9)
    assert (hemi.sampling.plan, hemi.solver.mode, hemi.process.friction) == ("sobol", "geodesic", 0.3)
    # the thesis reproductions run the thesis's blank-holder model
    assert {z.process.blankholder_model, sweep.process.blankholder_model, hemi.process.blankholder_model,
            load_study(STUDIES / "nosecone-blankholder-levels.toml").process.blankholder_model} == {"radial"}


# ---------------------------------------------------------------- defaults and sweeps


def test_defaults_are_filled(tmp_path):
    s = load_study(write(tmp_path, BASE, "ok.toml"))
    assert (s.chunk_size, s.description) == (64, "")
    assert s.fabric.orientation_deg == 0.0 and s.fabric.pre_shear_deg == 0.0
    assert s.fabric.crossover == (0.0, 0.0)
    assert s.process.friction == 0.2 and s.process.sectors is None and s.process.blankholder_model == "slip"
    assert s.solver.mode == "energy" and s.solver.tolerance_deg == 1e-3 and s.solver.max_iterations == 30
    assert s.sampling.plan == "monte_carlo"
    assert s.sensitivity.method == "none" and s.sensitivity.base_samples is None
    assert s.sensitivity.qoi == QOIS
    assert s.report.histogram_nodes == () and s.report.experimental_csv is None
    assert s.output_dir == Path("results/t")
    assert s.uncertainty.fields == {} and s.uncertainty.factors == {}
    # the mould's own defaults are filled in too, and rebuild the same mould
    assert s.geometry.params == {"radius": 100.0, "flange_half_width": 200.0}
    assert s.geometry.build_mould().inside(150.0, 0.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.seed = 2


def test_single_force_and_sweep(tmp_path):
    one = load_study(write(tmp_path, force("126"), "one.toml"))
    assert one.force_levels == (126.0,) and not one.is_sweep
    assert isinstance(one.force_levels[0], float)
    sweep = load_study(write(tmp_path, force("[0, 126, 252.0, 378]"), "sweep.toml"))
    assert sweep.force_levels == (0.0, 126.0, 252.0, 378.0) and sweep.is_sweep
    d = sweep.to_dict()
    assert d["process"]["blankholder_force_N"] == [0.0, 126.0, 252.0, 378.0]
    assert one.to_dict()["process"]["blankholder_force_N"] == 126.0


def test_every_shipped_study_round_trips_through_its_dict():
    """to_dict (the provenance stored with every ensemble) and from_dict are inverses, JSON between."""
    for f in sorted(STUDIES.glob("*.toml")):
        study = load_study(f)
        again = from_dict(json.loads(json.dumps(study.to_dict())), f)
        assert again == study, f.name


def test_to_dict_is_plain_json_in_file_layout(tmp_path):
    text = BASE + """
[uncertainty.spacing]
cv = 0.01
correlation = "squared_exponential"
length_mm = [20, 40]

[uncertainty.friction]
dist = "truncnormal"
mean = 0.2
sd = 0.05
bounds = [0.1, 0.3]

[sensitivity]
method = "sobol"
base_samples = 64
qoi = ["asymmetry"]
"""
    s = load_study(write(tmp_path, text, "ok.toml"))
    d = json.loads(json.dumps(s.to_dict()))
    assert d["uncertainty"]["friction"] == {"dist": "truncnormal", "mean": 0.2, "sd": 0.05, "bounds": [0.1, 0.3]}
    assert d["uncertainty"]["spacing"]["length_mm"] == [20.0, 40.0]
    assert d["sensitivity"] == {"method": "sobol", "qoi": ["asymmetry"], "base_samples": 64}
    assert d["study"]["chunk_size"] == 64 and d["output"]["directory"] == "results/t"
    # the field spec builds the stochastic input it was validated with
    inp = s.uncertainty.fields["spacing"].build_input(s.solver.rings, s.fabric.spacing_mm)
    assert inp.cv == 0.01 and inp.n_variables == 2 * (8 * 9)


def test_relative_paths_resolve_against_the_study_file(tmp_path):
    sub = tmp_path / "cards"
    sub.mkdir()
    (sub / "mine.csv").write_text("angle_deg,ns_positive\n0,0\n20,50\n40,200\n60,900\n")
    (sub / "exp.csv").write_text("distance_mm,shear_deg,quadrant_sign\n0,0,1\n")
    text = edit('"generic_woven"', '"cards/mine.csv"') + '\n[report]\nexperimental_csv = "cards/exp.csv"\n'
    s = load_study(write(tmp_path, text, "ok.toml"))
    assert Path(s.fabric.material) == (sub / "mine.csv").resolve()
    assert s.report.experimental_csv == (sub / "exp.csv").resolve()


# ---------------------------------------------------------------- malformed studies

SPACING = "\n[uncertainty.spacing]\ncv = 0.01\n"
FRICTION = '\n[uncertainty.friction]\ndist = "uniform"\nbounds = [0.1, 0.3]\n'

# (case id, file text, substrings the message must contain: the key and a hint of what is valid)
BAD = [
    ("toml-syntax", edit("seed = 1", "seed = = 1"), ["not valid TOML", "line 3"]),
    ("unknown-section", BASE + "\n[solve]\nrings = 3\n", ["unknown section [solve]", "valid sections", "solver"]),
    ("missing-section", BASE.replace("[solver]\nrings = 4\n", ""), ["[solver] is missing"]),
    ("unknown-key", edit('name = "t"', 'name = "t"\nnmae = "x"'),
     ["study.nmae", "valid keys in [study]: name, seed, realizations"]),
    ("bool-not-number", edit("seed = 1", "seed = true"), ["study.seed = true", "integer with 0 <= seed < 9223372036854775808"]),
    ("float-not-int", edit("realizations = 8", "realizations = 8.5"),
     ["study.realizations = 8.5", "integer >= 1"]),
    ("bad-name", edit('name = "t"', 'name = "my study"'), ['study.name = "my study"', "letters, digits"]),
    ("unknown-kind", edit('"hemisphere"', '"sphere"'), ['geometry.kind = "sphere"', '"hemisphere"', '"nose_cone"']),
    ("bad-shape-value", edit("radius = 100.0", "radius = -5.0"), ["geometry.radius = -5.0", "positive length"]),
    ("unknown-shape-key", edit("radius = 100.0", "radius = 100.0\nhalf_width = 3.0"),
     ["geometry.half_width", "valid keys in [geometry]: kind, radius, flange_half_width"]),
    ("mesh-without-path", edit('kind = "hemisphere"\nradius = 100.0', 'kind = "mesh"'),
     ["geometry.path is missing"]),
    ("mesh-not-found", edit('kind = "hemisphere"\nradius = 100.0', 'kind = "mesh"\npath = "nope.stl"'),
     ['geometry.path = "nope.stl"', "file not found"]),
    ("unknown-material", edit('"generic_woven"', '"kevlar"'),
     ['fabric.material = "kevlar"', "ebxhd936_like", "fge106hd_like"]),
    ("zero-spacing", edit("spacing_mm = 5.0", "spacing_mm = 0"), ["fabric.spacing_mm = 0", "0.01 <= spacing_mm < 1000"]),
    ("pre-shear-range", edit("spacing_mm = 5.0", "spacing_mm = 5.0\npre_shear_deg = 95"),
     ["fabric.pre_shear_deg = 95", "-90 < pre_shear_deg < 90"]),
    ("crossover-outside", edit("spacing_mm = 5.0", "spacing_mm = 5.0\ncrossover = [500.0, 0.0]"),
     ["fabric.crossover = [500.0, 0.0]", "inside the mould", "[-200, 200]"]),
    ("crossover-shape", edit("spacing_mm = 5.0", "spacing_mm = 5.0\ncrossover = [1.0]"),
     ["fabric.crossover = [1.0]", "two numbers [x, y]"]),
    ("empty-sweep", force("[]"), ["process.blankholder_force_N = []", "non-empty list"]),
    ("negative-force", force("[0, -10]"), ["process.blankholder_force_N = [0, -10]", ">= 0"]),
    ("negative-friction", force("100.0", "\nfriction = -0.1"), ["process.friction = -0.1", ">= 0"]),
    ("all-zero-sectors", force("100.0", "\nsectors = [0, 0]"), ["process.sectors", "not all zero"]),
    ("bad-blankholder-model", force("100.0", '\nblankholder_model = "circular"'),
     ['process.blankholder_model = "circular"', '"slip"', '"radial"']),
    ("bad-mode", edit("rings = 4", 'rings = 4\nmode = "fast"'), ['solver.mode = "fast"', '"geodesic"', '"energy"']),
    ("missing-rings", edit("rings = 4", "max_iterations = 3"), ["solver.rings is missing", "integer >= 1"]),
    ("cv-too-big", BASE + "\n[uncertainty.spacing]\ncv = 1.2\n",
     ["uncertainty.spacing.cv = 1.2 is invalid", "[0, 1)"]),
    ("correlated-without-length", BASE + '\n[uncertainty.spacing]\ncv = 0.01\ncorrelation = "exponential"\n',
     ["uncertainty.spacing.length_mm is missing", "required"]),
    ("length-with-iid", BASE + "\n[uncertainty.spacing]\ncv = 0.01\nlength_mm = [20, 20]\n",
     ["uncertainty.spacing.length_mm = [20, 20]", '"exponential"']),
    ("bad-length", BASE + '\n[uncertainty.spacing]\ncv = 0.01\ncorrelation = "exponential"\nlength_mm = [20, -1]\n',
     ["uncertainty.spacing.length_mm = [20, -1]", "positive"]),
    ("kl-retained", BASE + "\n[uncertainty.spacing]\ncv = 0.01\nkl_retained = 1.5\n",
     ["uncertainty.spacing.kl_retained = 1.5", "(0, 1]"]),
    ("negative-sd-deg", BASE + "\n[uncertainty.zero_angle]\nsd_deg = -1.0\n",
     ["uncertainty.zero_angle.sd_deg = -1.0", "sd_deg >= 0"]),
    ("unknown-factor", BASE + '\n[uncertainty.speed]\ndist = "normal"\n',
     ["uncertainty.speed", "valid keys in [uncertainty]: spacing, zero_angle, stitch_prestrain, blankholder_force"]),
    ("unknown-dist", BASE + '\n[uncertainty.friction]\ndist = "beta"\n',
     ['uncertainty.friction.dist = "beta"', '"uniform"', '"lognormal"']),
    ("dist-keys", BASE + '\n[uncertainty.friction]\ndist = "uniform"\nmean = 0.2\n',
     ["uncertainty.friction.mean", "valid keys in [uncertainty.friction]: dist, bounds"]),
    ("reversed-bounds", BASE + '\n[uncertainty.friction]\ndist = "uniform"\nbounds = [0.3, 0.1]\n',
     ["uncertainty.friction.bounds = [0.3, 0.1]", "lower must be < upper"]),
    ("negative-friction-factor", BASE + '\n[uncertainty.friction]\ndist = "normal"\nmean = 0.05\nsd = 0.05\n',
     ["uncertainty.friction = ", "friction must lie in [0, 2]", "truncnormal"]),
    ("sweep-and-force-factor",
     force("[0, 100]") + '\n[uncertainty.blankholder_force]\ndist = "uniform"\nbounds = [0, 50]\n',
     ["process.blankholder_force_N = [0.0, 100.0]", "cannot be combined"]),
    ("crossover-factor-outside", BASE + '\n[uncertainty.crossover_x]\ndist = "uniform"\nbounds = [-10, 250]\n',
     ["uncertainty.crossover_x", "leave the mould's domain"]),
    ("sobol-plan-not-power-of-two", edit("realizations = 8", "realizations = 10") + '\n[sampling]\nplan = "sobol"\n',
     ['sampling.plan = "sobol"', "study.realizations = 10", "power-of-two"]),
    ("sensitivity-needs-base-samples", BASE + SPACING + '\n[sensitivity]\nmethod = "sobol"\n',
     ["sensitivity.base_samples is missing", "integer >= 1"]),
    ("sobol-base-samples", BASE + SPACING + '\n[sensitivity]\nmethod = "sobol"\nbase_samples = 100\n',
     ["sensitivity.base_samples = 100", "power of 2"]),
    ("morris-base-samples", BASE + SPACING + '\n[sensitivity]\nmethod = "morris"\nbase_samples = 4\n',
     ["sensitivity.base_samples = 4", "minimum is 10"]),
    ("sensitivity-needs-inputs", BASE + '\n[sensitivity]\nmethod = "morris"\nbase_samples = 10\n',
     ['sensitivity.method = "morris"', "[uncertainty.*]"]),
    ("base-samples-without-method", BASE + "\n[sensitivity]\nbase_samples = 64\n",
     ["sensitivity.base_samples = 64", '"sobol"']),
    ("unknown-qoi", BASE + FRICTION + '\n[sensitivity]\nqoi = ["max_shear"]\n',
     ['sensitivity.qoi = ["max_shear"]', "max_abs_shear"]),
    ("histogram-node-outside", BASE + "\n[report]\nhistogram_nodes = [[1, 1], [5, 0]]\n",
     ["report.histogram_nodes = [[1, 1], [5, 0]]", "|i|, |j| <= rings = 4"]),
    ("unknown-report-key", BASE + '\n[report]\nlines = "min"\n', ["unknown key report.lines", "histogram_nodes"]),
    ("experimental-csv-missing", BASE + '\n[report]\nexperimental_csv = "exp.csv"\n',
     ['report.experimental_csv = "exp.csv"', "file not found"]),
    ("section-not-table", 'output = "here"\n' + BASE,
     ['output = "here"', "must be a table [output]"]),
]


@pytest.mark.parametrize("text, expected", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_malformed_study_is_explained(tmp_path, text, expected):
    path = write(tmp_path, text)
    with pytest.raises(StudyError) as info:
        load_study(path)
    msg = str(info.value)
    assert isinstance(info.value, ValueError)
    assert msg.startswith(f"{path}: ")  # the file first
    assert_one_line_error(msg, file=path, valid=expected)


def test_first_error_in_schema_order(tmp_path):
    # two problems: [fabric] comes after [study], whatever the order in the file
    text = edit("spacing_mm = 5.0", "spacing_mm = -1.0").replace("[study]", "[study]\nchunk_size = 0", 1)
    text = text[text.index("[geometry]"):] + text[: text.index("[geometry]")]
    with pytest.raises(StudyError, match=r"study\.chunk_size = 0"):
        load_study(write(tmp_path, text))


def test_missing_file_is_a_study_error(tmp_path):
    with pytest.raises(StudyError, match="nothere.toml: cannot read"):
        load_study(tmp_path / "nothere.toml")


def test_sensitivity_methods_match_the_sensitivity_package():
    import uqdrape.sensitivity

    assert set(SENSITIVITY_METHODS) == {*uqdrape.sensitivity.METHODS, "none"}


# ---------------------------------------------------------------- the validate command


def test_validate_bad_file_exits_2_without_traceback(tmp_path, capsys):
    path = write(tmp_path, BASE + "\n[uncertainty.spacing]\ncv = 1.2\n")
    assert cli(["validate", str(path)]) == 2
    out, err = capsys.readouterr()
    assert_one_line_error(err, file=path, key="uncertainty.spacing.cv", value="1.2")
    assert out == ""


def test_validate_good_files_exit_0(capsys):
    files = [str(STUDIES / "nosecone-blankholder-sweep.toml"), str(STUDIES / "hemisphere-skew.toml")]
    assert cli(["validate", *files]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert "nosecone-blankholder-sweep: 64 realisations" in out
    assert "sweep 0, 126, 252, 378 N" in out
    assert "skew ~ uniform(lower=0, upper=55)" in out


def test_validate_usage_error_exits_2(capsys):
    with pytest.raises(SystemExit) as stop:
        cli(["validate"])
    assert stop.value.code == 2
    assert "usage: uqdrape validate" in capsys.readouterr().err
