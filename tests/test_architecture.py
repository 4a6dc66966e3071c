"""Tests of uqdrape.material.architecture: the thesis ch. 4 NCF model and derived cards.

Hand numbers (thesis-notes §2.3, FGE 106hd, tricot, s_l 2.5 mm, s_g 25.4/6 mm, s_t 2 mm):
s_L(0) = 2·2·(2.5 + 2) + 2·sqrt(2.5² + 4.2333²) = 27.833 mm, A_s = 2·2.5·4.2333 = 21.167 mm².
The numbers compared against live in golden.py with their sources.
"""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid
from scipy.optimize import brentq

from uqdrape.cli import main
from uqdrape.material import load_material
from uqdrape.material.architecture import (
    HEXAGONAL_VA,
    Architecture,
    available_architectures,
    bulk_stress,
    derive_card,
    load_architecture,
    stitch_length,
    stitch_strain,
    summed,
    zero_force_angle,
    zero_force_table,
)
from uqdrape.material.cards import card_material, card_text, material_document

from conftest import assert_one_line_error, write_study
from golden import (
    FGE_5MM_STITCH_FAILURE_DEG,
    FGE_ASYMMETRY_AT_30_DEG,
    FGE_CALIBRATED,
    FGE_CROSSOVER_TO_COMPACTION,
    FGE_LOCKING_ANGLE_DEG,
    FGE_NEGATIVE_NS_TARGET_N_PER_M,
    FGE_STITCH_LENGTH_MM,
    FGE_STITCH_STRAIN_PCT,
    FGE_STITCH_TENSION_PEAK,
    FGE_UNIT_AREA_MM2,
    FGE_ZERO_FORCE_ANGLE_DEG,
    FGE_ZERO_FORCE_TARGET_DEG,
)

SG = 25.4 / 6.0
ARCH_DIR = Path(__file__).resolve().parent.parent / "uqdrape" / "material" / "architectures"


def fge(**changes):
    return replace(Architecture("fge", stitch_length_mm=2.5, gauge=6, prestrain=0.0, beta=460.0), **changes)


def hand_length(theta_deg, s_l=2.5, lapping=(1, -1), s_t=2.0):
    """Eq 4.1, 4.2, 4.6 at φ0 = 45°, written out."""
    phi = math.radians(45.0 - theta_deg / 2.0)
    c, s = math.cos(phi) / math.cos(math.radians(45)), math.sin(phi) / math.sin(math.radians(45))
    return sum(2 * c * s_l + 2 * s_t + math.hypot(c * s_l, s * n * SG) for n in lapping)


def at(terms, deg, key):
    k = int(np.argmin(np.abs(np.rad2deg(terms["theta"]) - deg)))
    assert abs(np.rad2deg(terms["theta"][k]) - deg) < 1e-9
    return float(terms[key][k])


@pytest.fixture(scope="module")
def shipped():
    return {name: load_architecture(name) for name in available_architectures()}


@pytest.fixture(scope="module")
def fge_terms():
    return summed(fge())


def test_fge106hd_stitch_geometry_matches_the_hand_numbers():
    a = fge()
    assert stitch_length(a, 0.0) == pytest.approx(18.0 + 2.0 * math.hypot(2.5, SG), rel=1e-12)
    assert stitch_length(a, 0.0) == pytest.approx(FGE_STITCH_LENGTH_MM, abs=5e-4)
    assert a.unit_area_mm2 == pytest.approx(FGE_UNIT_AREA_MM2, abs=5e-5)
    strain = 100.0 * stitch_strain(a, np.deg2rad([15.0, 30.0, 45.0, 60.0, -30.0]))
    np.testing.assert_allclose(strain, FGE_STITCH_STRAIN_PCT, atol=5e-5)
    for deg, pct in zip((15, 30, 45, 60, -30), strain):
        assert pct == pytest.approx(100.0 * (hand_length(deg) / hand_length(0) - 1.0), abs=1e-9)


@pytest.mark.parametrize("lapping", [(0, 0), (1, 0, -1, 0), (2, -2), (1, -1)])
def test_any_lapping_sequence(lapping):
    a = fge(lapping=lapping)
    for deg in (0.0, 20.0, -35.0):
        assert stitch_length(a, math.radians(deg)) == pytest.approx(hand_length(deg, lapping=lapping), rel=1e-12)
    assert a.unit_area_mm2 == pytest.approx(len(lapping) * 2.5 * SG, rel=1e-12)


def test_stitch_tension_peaks_at_35_N_per_m_near_28_deg_and_matches_the_closed_form(fge_terms):
    """Zero pre-strain: N_s = E_s s_A ε (ds_L/dθ)/(A_s cos θ) with the corrected derivatives
    ds_u/dθ = s_l sin φ/(2 cos φ0) and ds_o/dθ = sin 2φ (s_l² tan φ0 − n² s_g²/tan φ0)/(2 sin 2φ0 s_o)."""
    deg = np.rad2deg(fge_terms["theta"])
    ns = fge_terms["ns_stitch_tension"]
    k = int(np.argmax(ns))
    peak_deg, peak_ns = FGE_STITCH_TENSION_PEAK
    assert deg[k] == pytest.approx(peak_deg, abs=1e-9) and ns[k] == pytest.approx(peak_ns, rel=1e-6)
    for d in (10.0, 30.0, 50.0):
        phi = math.radians(45.0 - d / 2.0)
        s_o = math.hypot(2.5 * math.cos(phi) / math.cos(math.pi / 4), SG * math.sin(phi) / math.sin(math.pi / 4))
        dsu = 2.5 * math.sin(phi) / (2.0 * math.cos(math.pi / 4))
        dso = math.sin(2 * phi) * (2.5**2 - SG**2) / (2.0 * s_o)
        ds_l = 2 * 2 * dsu + 2 * dso  # mm per rad
        eps = hand_length(d) / hand_length(0) - 1.0
        closed = 15.725 * eps * ds_l / (2 * 2.5 * SG * math.cos(math.radians(d))) * 1e3
        assert at(fge_terms, d, "ns_stitch_tension") == pytest.approx(closed, rel=2e-5)
    # the stitch is slack in negative shear: no tension, no friction
    assert np.all(fge_terms["ns_stitch_tension"][deg < 0] == 0.0)
    assert np.all(fge_terms["stitch_friction"][deg < 0] == 0.0)


@pytest.mark.parametrize("prestrain, expected", FGE_ZERO_FORCE_ANGLE_DEG.items())
def test_prestrain_puts_the_zero_force_angle_where_the_stitch_goes_slack(prestrain, expected):
    a = fge(prestrain=prestrain)
    slack = brentq(lambda d: hand_length(d) - hand_length(0) / (1 + prestrain), -30.0, 0.0)
    gamma0 = zero_force_angle(a)
    assert gamma0 == pytest.approx(slack, abs=0.05)  # to within the 0.05 deg grid step
    assert gamma0 == pytest.approx(expected, rel=1e-6)
    assert zero_force_angle(fge()) == 0.0


def test_stitch_length_trend_of_fig_4_21(shipped):
    """+/- N_s at 30 deg: 1.65 mm symmetric (its stitch shortens both ways and goes slack),
    2.5 mm about 2220:1, 5 mm about 15000:1 (the negative branch is compaction alone)."""
    ratio = {}
    for name in ("fge106hd_1p65mm", "fge106hd", "fge106hd_5mm"):
        t = summed(shipped[name])
        ratio[name] = at(t, 30.0, "ns_total") / -at(t, -30.0, "ns_total")
    assert ratio["fge106hd_1p65mm"] == pytest.approx(1.0, abs=1e-9)
    for name, expected in FGE_ASYMMETRY_AT_30_DEG.items():
        assert ratio[name] == pytest.approx(expected, abs=1), name


def test_the_5mm_stitch_fails_at_17_percent_and_its_terms_end(shipped):
    a = shipped["fge106hd_5mm"]
    t = summed(a)
    deg = np.rad2deg(t["theta"])
    strain = stitch_strain(a, t["theta"])
    fail = deg[np.argmax((deg > 0) & (strain >= 0.17))]
    after = deg > fail
    assert fail == pytest.approx(FGE_5MM_STITCH_FAILURE_DEG, abs=1e-9)  # a point of the 0.05 deg grid
    for term in ("ns_stitch_tension", "ns_stitch_friction"):  # constant energy: zero to rounding
        assert np.abs(t[term][after]).max() < 1e-9


def test_compaction_locks_at_67_3_deg_and_crossover_friction_is_small(fge_terms):
    a = fge()
    lock = math.degrees(math.acos(0.35 / (math.pi / (2 * math.sqrt(3)))))
    assert a.locking_angle_deg == pytest.approx(lock, abs=1e-9) and lock == pytest.approx(FGE_LOCKING_ANGLE_DEG, abs=0.005)
    assert np.isinf(bulk_stress(a, HEXAGONAL_VA)) and bulk_stress(a, 0.35) == 0.0
    # the ratio does not depend on beta (both scale as 1/beta^4)
    for deg, expected in FGE_CROSSOVER_TO_COMPACTION.items():
        r = at(fge_terms, deg, "ns_crossover") / at(fge_terms, deg, "ns_compaction")
        assert r == pytest.approx(expected, rel=1e-6)
    # Fig 4.12: linear in the crossover side
    doubled = summed(fge(crossover_side_mm=2 * 1.87))
    assert at(doubled, 45.0, "ns_crossover") == pytest.approx(2.0 * at(fge_terms, 45.0, "ns_crossover"), rel=1e-12)


def test_energy_and_shear_force_are_consistent(fge_terms):
    theta = fge_terms["theta"]
    for side in (theta >= 0.0, theta <= 0.0):
        t = theta[side]
        order = np.argsort(np.abs(t))
        t = t[order]
        w = fge_terms["total"][side][order]
        rebuilt = cumulative_trapezoid(fge_terms["ns_total"][side][order] * np.cos(t), t, initial=0.0)
        keep = np.abs(t) < np.deg2rad(60.0)
        assert np.max(np.abs(rebuilt[keep] - w[keep])) < 0.004  # J/m², W up to 52 J/m²


def test_tabulated_yarn_curve_equals_the_linear_law_it_tabulates():
    strain = (0.0, 0.05, 0.1, 0.2)
    tab = fge(stitch_stiffness_N=None, tension_curve=(strain, tuple(15.725 * e for e in strain)), prestrain=0.004)
    lin = summed(fge(prestrain=0.004), np.deg2rad(np.linspace(-40, 40, 801)))
    other = summed(tab, np.deg2rad(np.linspace(-40, 40, 801)))
    np.testing.assert_allclose(other["total"], lin["total"], rtol=1e-12, atol=1e-12)


def test_calibration_hits_its_targets(shipped):
    a = shipped["fge106hd"]
    assert zero_force_angle(a) == pytest.approx(FGE_ZERO_FORCE_TARGET_DEG, abs=1e-4)
    assert -at(summed(a), -60.0, "ns_total") == pytest.approx(FGE_NEGATIVE_NS_TARGET_N_PER_M, rel=1e-6)
    assert a.prestrain == pytest.approx(FGE_CALIBRATED["prestrain"], abs=1e-6)
    assert a.beta == pytest.approx(FGE_CALIBRATED["beta"], abs=0.01)
    for name in ("fge106hd_1p65mm", "fge106hd_5mm", "ebxhd936"):
        assert (shipped[name].prestrain, shipped[name].beta) == (a.prestrain, a.beta)
        assert shipped[name].calibration["from"] == "fge106hd.toml"


def test_zero_force_table_maps_arrays_and_refuses_past_its_range(shipped):
    a = shipped["fge106hd"]
    table = zero_force_table(a)
    assert table(a.prestrain) == pytest.approx(FGE_ZERO_FORCE_TARGET_DEG, abs=0.02)
    values = table(np.array([[-0.01, 0.0], [0.005, 0.01]]))
    np.testing.assert_allclose(values, [[0.0, 0.0], [FGE_ZERO_FORCE_ANGLE_DEG[0.005], FGE_ZERO_FORCE_ANGLE_DEG[0.01]]],
                               atol=0.001)
    assert np.all(np.diff(table.gamma0_deg) < 0)
    with pytest.raises(ValueError, match="beyond the mapped range"):
        table(0.05)


@pytest.mark.parametrize("name", ["fge106hd", "fge106hd_1p65mm", "fge106hd_5mm", "ebxhd936"])
def test_shipped_derived_cards_are_current_and_round_trip(shipped, name):
    doc = derive_card(shipped[name], name=f"{name}_derived", source=f"{name}.toml")
    text = card_text(doc)
    material = card_material(text, f"{name}_derived.toml")
    assert card_text(material_document(material)) == text
    shipped_card = load_material(f"{name}_derived")
    assert material_document(shipped_card) == material_document(material)
    assert shipped_card.architecture["model"] == "wiggers2007-ch4/1"


def test_derive_command_writes_card_and_plot(tmp_path, capsys):
    out = tmp_path / "cards" / "fge.toml"
    assert main(["materials", "derive", "fge106hd", "--out", str(out), "--plot"]) == 0
    assert out.is_file() and out.with_suffix(".png").stat().st_size > 10_000
    m = load_material(out)
    assert m.name == "fge" and m.architecture["zero_force_angle_deg"] == pytest.approx(FGE_ZERO_FORCE_TARGET_DEG, abs=1e-4)
    assert "zero-force angle -2.30 deg" in capsys.readouterr().out


GOOD = (ARCH_DIR / "fge106hd.toml").read_text(encoding="utf-8")


@pytest.mark.parametrize("old, new, key", [
    ("length_mm = 2.5 ", "length_mm = -2.5 ", "stitch.length_mm"),
    ("length_mm = 2.5 ", "length_mm = 0 ", "stitch.length_mm"),
    ("gauge = 6 ", "gauge = 0 ", "stitch.gauge"),
    ("lapping = [1, -1]", "lapping = []", "stitch.lapping"),
    ("lapping = [1, -1]", "lapping = [1, 0]", "stitch.lapping"),
    ('prestrain = "calibrate"', "prestrain = 0.2", "stitch.prestrain"),
    ("vf0 = 0.35 ", "vf0 = 0.95 ", "compaction.vf0"),
    ("thickness_mm = 2.0 ", "thickness_mm = -1.0 ", "thickness_mm"),
    ("zero_force_angle_deg = -2.3 ", 'from = "bad.toml" #', "calibration.from"),
])
def test_bad_architecture_is_one_line_naming_the_key_and_writes_nothing(tmp_path, capsys, old, new, key):
    assert old in GOOD
    path = tmp_path / "bad.toml"
    path.write_text(GOOD.replace(old, new), encoding="utf-8")
    out = tmp_path / "card.toml"
    assert main(["materials", "derive", str(path), "--out", str(out), "--plot"]) == 2
    assert_one_line_error(capsys.readouterr().err, file=path, key=key, valid=[f"{key} = "])
    assert not out.exists() and not out.with_suffix(".png").exists()


@pytest.mark.parametrize("old, new, key, words", [
    ("[stitch]\n", "[stitch]\nlenght_mm = 2.5\n", "stitch.lenght_mm",
     ["valid keys in [stitch]: length_mm, gauge, lapping, stiffness_N, tension_curve"]),
    ("length_mm = 2.5 ", "# ", "stitch.length_mm", ["stitch.length_mm is missing: stitch.length_mm is the stitch length"]),
    ('prestrain = "calibrate"', 'prestrain = "fit"', "stitch.prestrain", ['prestrain must be a number or "calibrate"']),
    ("lapping = [1, -1]", "lapping = [1, -1.0]", "stitch.lapping", ["stitch.lapping = [1, -1.0] is invalid"]),
    ("zero_force_angle_deg = -2.3 ", "zero_force_angle_deg = -80 ", "calibration", ["the fit failed", "must lie in"]),
    ("[compaction]", "[compactio]", "compactio", ["unknown key compactio; valid keys in the file's top level: name",
                                                  "compaction, crossover, calibration"]),
])
def test_architecture_errors_carry_the_file_key(tmp_path, old, new, key, words):
    from uqdrape.files import FileFormatError

    assert old in GOOD
    path = tmp_path / "bad.toml"
    path.write_text(GOOD.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(FileFormatError) as err:
        load_architecture(path)
    message = str(err.value)
    assert message.startswith(f"{path}: ") and err.value.key == key and all(w in message for w in words), message


# -- stochastic architecture: a stitch pre-strain field mapped to gamma0 per cell ----------
def study_file(tmp_path, material="fge106hd_derived", mean=FGE_CALIBRATED["prestrain"], sd=0.001, other=None):
    """A plate study of ``material`` with a stitch pre-strain field (and the ``other`` inputs)."""
    return write_study(tmp_path, "pre", study={"seed": 7, "realizations": 3, "chunk_size": None},
                       geometry={"kind": "plate", "radius": None}, fabric={"material": material},
                       process={"blankholder_force_N": 0}, solver={"mode": "energy"},
                       uncertainty={**(other or {}), "stitch_prestrain": {"mean": mean, "sd": sd}}, output=None)


def test_prestrain_field_becomes_gamma0_through_the_cards_architecture(tmp_path, shipped):
    from uqdrape.ensemble.inputs import sampled_inputs
    from uqdrape.study import load_study

    table = zero_force_table(shipped["fge106hd"])
    constant = sampled_inputs(load_study(study_file(tmp_path, sd=0.0)), [0, 2])["gamma0"]
    assert constant.shape == (2, 8, 8)
    np.testing.assert_allclose(constant, table(FGE_CALIBRATED["prestrain"]), rtol=0, atol=1e-12)
    assert constant[0, 0, 0] == pytest.approx(FGE_ZERO_FORCE_TARGET_DEG, abs=0.02)  # the card's own zero-force angle
    noisy = sampled_inputs(load_study(study_file(tmp_path, sd=0.002)), [1])["gamma0"]
    assert noisy.std() > 0.5 and np.all(noisy <= 0.0)  # a slack stitch (ε0 < 0) rests at 0


@pytest.mark.parametrize("material, sd, other, words", [
    ("fge106hd_like", 0.001, None, "has no [architecture] record"),
    ("fge106hd_derived", 0.005, None, "passes the largest mapped pre-strain 0.03"),
    ("ebxhd936_derived", 0.001, None, "is 0 deg at every pre-strain up to 0.03"),
    ("fge106hd_derived", 0.001, {"zero_angle": {"sd_deg": 5.0}}, "remove [uncertainty.zero_angle]"),
])
def test_prestrain_field_errors_name_file_and_key(tmp_path, material, sd, other, words):
    from uqdrape.study import StudyError, load_study

    path = study_file(tmp_path, material=material, sd=sd, other=other)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert str(err.value).startswith(str(path))
    assert_one_line_error(str(err.value), file=path, key="uncertainty.stitch_prestrain", valid=[words])
