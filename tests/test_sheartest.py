"""Shear tests -> material cards (uqdrape.material.sheartest, thesis ch. 3).

Synthetic specimens are made from a known N_s(θ) through the exact forward balance of
each rig, with Gaussian load-cell noise of sd NOISE_N and a friction jump, written as
test CSVs with a rig file, and fitted back through the same path as the CLI. "Within
the noise" means: at every angle of the valid range the card is nearer the generating
curve than the sd of one normalised data point (`point_noise`), i.e. the fit does at
least as well as a single row would.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import assert_one_line_error

from uqdrape.cli import main
from uqdrape.material import load_material, plot
from uqdrape.material.sheartest import BiasExtension, PictureFrame, ShearTestError, fit_card, read_rig
from uqdrape.material.sheartest.bias_extension import halving_solve
from uqdrape.material.sheartest.picture_frame import shear_per_crosshead

#: Load-cell noise (N), Gaussian sd: 0.3 % of the picture frame's 180 N peak here.
NOISE_N = 0.5
#: Friction jump (N) at the start of every test, rising over ~1/5 deg.
FRICTION_N = 2.0
ROWS = 1500


def ns_true(theta):
    """The generating shear force (N/m) at θ (rad): near-linear, then stiffening to 672
    N/m at 60 deg (the scale of the thesis's picture-frame axes)."""
    deg = np.rad2deg(theta)
    return 1.2 * deg + 600.0 * (deg / 60.0) ** 4


def point_noise(rig, theta):
    """The sd (N/m) of one row's normalised N_s when its force has sd NOISE_N: PF Eq 3.1,
    F/(2 L cos φ); BE the row's share of the balance, (κ−1)F/((2κ−3) 2 L3 cos φ)."""
    cos_phi = np.cos(rig.phi0 - theta / 2.0)
    if isinstance(rig, PictureFrame):
        return NOISE_N / (2e-3 * rig.side_mm * cos_phi)
    k = rig.kappa
    return NOISE_N * (k - 1.0) / ((2.0 * k - 3.0) * 2e-3 * rig.side_mm * cos_phi)


def write_specimen(path, rig, rng, *, scale=1.0, max_deg=62.0, measured=False, slip_from_deg=None):
    """A test CSV of ``rig`` for N_s = scale · ns_true; ``measured``: an angle column (sd
    0.2 deg); ``slip_from_deg``: beyond it the crosshead runs ahead of the shear by
    0.5 mm per degree (grip slip), so kinematic and measured θ part."""
    theta = np.linspace(0.0, np.deg2rad(max_deg), ROWS)
    force = rig.crosshead_force(lambda t: scale * ns_true(t), theta)
    force += FRICTION_N * (1.0 - np.exp(-np.rad2deg(theta) / 0.2)) + rng.normal(0.0, NOISE_N, ROWS)
    disp = rig.displacement(theta)
    if slip_from_deg is not None:
        disp += 0.5 * np.maximum(np.rad2deg(theta) - slip_from_deg, 0.0)
    columns = [force, disp] + ([np.rad2deg(theta) + rng.normal(0.0, 0.2, ROWS)] if measured else [])
    header = "force_n,displacement_mm" + (",angle_deg" if measured else "")
    rows = "\n".join(",".join(f"{v:.6f}" for v in row) for row in zip(*columns))
    path.write_text(f"# synthetic {rig.describe()}\n{header}\n{rows}\n", encoding="utf-8")
    return path


def write_rig(path, test, specimens, *, fit="", **keys):
    """A rig file: ``keys`` at the top, ``fit`` the [fit] table's lines, ``specimens`` a
    list of (file, branch) or (file, branch, extra lines)."""
    lines = [f'test = "{test}"', *(f"{k} = {v!r}" if not isinstance(v, str) else f'{k} = "{v}"'
                                  for k, v in keys.items())]
    if fit:
        lines += ["[fit]", fit]
    for spec in specimens:
        lines += ["[[specimen]]", f'file = "{spec[0]}"', f'branch = "{spec[1]}"', *spec[2:]]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def fitted(tmp_path, rig, *, n=1, scales=None, seed=0, fit='friction = "subtract"', rig_keys=None, **specimen):
    """Fit a card to ``n`` synthetic specimens of ``rig`` (scales: their factors on ns_true)."""
    rng = np.random.default_rng(seed)
    scales = [1.0] * n if scales is None else scales
    files = [write_specimen(tmp_path / f"s{i}.csv", rig, rng, scale=s, **specimen).name for i, s in enumerate(scales)]
    if isinstance(rig, PictureFrame):
        keys = dict(side_mm=rig.side_mm, phi0_deg=rig.phi0_deg)
        test = "picture_frame"
    else:
        keys = dict(height_mm=rig.height_mm, width_mm=rig.width_mm, phi0_deg=rig.phi0_deg)
        test = "bias_extension"
    keys.update(rig_keys or {})
    path = write_rig(tmp_path / "rig.toml", test, [(f, "positive") for f in files], fit=fit, **keys)
    return fit_card(read_rig(path), "synthetic", path.name)


def card_curve(result, branch="positive"):
    curve = result.doc["shear"][branch]
    return np.deg2rad(np.asarray(curve["angle_deg"])), np.asarray(curve["ns"])


# ---------------------------------------------------------------- kinematics and balances


def test_picture_frame_kinematics_and_the_two_normalised_forces():
    pf = PictureFrame(145.0, 45.0)
    # Eq 3.4 at θ = 30 deg: 2·145·(cos 30° − cos 45°) = 46.0866 mm; Eq 3.5 inverts it
    assert pf.displacement(np.deg2rad(30.0)) == pytest.approx(290.0 * (np.sqrt(3) / 2 - np.sqrt(0.5)), rel=1e-12)
    theta = np.deg2rad(np.linspace(0.0, 85.0, 18))
    np.testing.assert_allclose(pf.shear_angle(pf.displacement(theta)), theta, atol=1e-12)
    assert np.isnan(pf.shear_angle(2.0 * 145.0))  # beyond the frame's closing
    # 100 N at θ = 0: F/L = 689.66 N/m (Eq 3.16), N_s = F/(2 L cos 45°) = 487.66 N/m (Eq 3.1)
    assert pf.normalised_force(100.0) == pytest.approx(100.0 / 0.145)
    assert pf.shear_force(lambda t: 100.0 + 0 * t, 0.0) == pytest.approx(100.0 / (0.29 * np.sqrt(0.5)))
    # non-orthogonal start: the crosshead force and N_s convert both ways
    pf30 = PictureFrame(145.0, 30.0)
    np.testing.assert_allclose(pf30.shear_force(lambda t: pf30.crosshead_force(ns_true, t), theta[:10]),
                               ns_true(theta[:10]), rtol=1e-12)


def test_f_over_l_to_f_s_over_l_by_hand_at_three_angles():
    """N_s = F_s/L = F/L · 1/(2 cos(φ0 − θ/2)) (Eq 3.1 over L), φ0 = 45 deg: at θ = 0, 30,
    60 deg the factor is 1/(2 cos 45°) = 1/√2 = 0.70711, 1/(2 cos 30°) = 1/√3 = 0.57735
    and 1/(2 cos 15°) = (√6 − √2)/2 = 0.51764."""
    theta = np.deg2rad([0.0, 30.0, 60.0])
    hand = np.array([1.0 / np.sqrt(2.0), 1.0 / np.sqrt(3.0), (np.sqrt(6.0) - np.sqrt(2.0)) / 2.0])
    np.testing.assert_allclose(hand, [0.70711, 0.57735, 0.51764], atol=5e-6)
    factor = shear_per_crosshead(theta, np.deg2rad(45.0))
    np.testing.assert_allclose(factor, hand, rtol=1e-14)
    f_over_l = np.array([100.0, 250.0, 700.0])  # N/m
    np.testing.assert_allclose(f_over_l * factor / factor, f_over_l, rtol=1e-15)  # F_s/L back to F/L
    pf = PictureFrame(145.0, 45.0)  # the rig's raw path agrees: N_s / (F/L) is the same factor
    np.testing.assert_allclose(pf.shear_force(lambda t: 14.5 + 0 * t, theta) / pf.normalised_force(14.5), hand,
                               rtol=1e-14)


def test_bias_extension_at_kappa_2_has_the_picture_frame_kinematics():
    be = BiasExtension(180.0, 90.0, 45.0)  # κ = 2, L3 = 90/(2 sin 45°) = 63.64 mm
    assert be.kappa == pytest.approx(2.0)
    assert be.side_mm == pytest.approx(45.0 * np.sqrt(2.0))
    theta = np.deg2rad(np.linspace(0.0, 80.0, 9))
    np.testing.assert_allclose(be.displacement(theta), PictureFrame(be.side_mm, 45.0).displacement(theta), rtol=1e-12)
    np.testing.assert_allclose(be.shear_angle(be.displacement(theta)), theta, atol=1e-12)


@pytest.mark.parametrize("height, width, phi0", [(180.0, 90.0, 45.0), (225.0, 90.0, 45.0), (270.0, 90.0, 45.0),
                                                 (242.0, 70.0, 30.0)])
def test_the_exact_bias_extension_inversion_undoes_the_forward_balance(height, width, phi0):
    be = BiasExtension(height, width, phi0)
    theta = np.deg2rad(np.linspace(0.5, 55.0, 12))
    force = lambda t: be.crosshead_force(ns_true, t)  # noqa: E731
    # the halving tail is exact to O(θ/2^20): 1e-6 relative at κ = 2, round-off above
    np.testing.assert_allclose(be.shear_force(force, theta), ns_true(theta), rtol=1e-6)


def test_halving_solve_solves_its_equation_also_at_a_1_with_a_start_offset():
    g = lambda t: 3.0 + 2.0 * t + np.sin(t)  # noqa: E731, g(0) = 3: the plain iteration oscillates at a = 1
    theta = np.linspace(0.0, 1.0, 11)
    for a in (1.0, 2.0, 3.0):
        y = lambda t: halving_solve(g, t, a)  # noqa: E731
        np.testing.assert_allclose(a * y(theta) + y(theta / 2.0), g(theta), atol=1e-6)


def test_the_thesis_routes_over_predict_by_a_few_per_cent():
    """Noise-free, κ = 2, φ0 = 45°: the thesis's iteration (Eq 3.34-3.35) and polynomial
    (Eq 3.39, 6th order) over-predict N_s by 1.9 % at 10°, 4.8 % at 30°, 6.5 % at 50°
    and 8.7 % at 60° (digest's check: 2-8 % over 10-60°); the excess halves at κ = 2.5
    (2.6 % at 30°) and shrinks again at κ = 3 (1.8 %)."""
    theta = np.deg2rad(np.array([10.0, 30.0, 50.0, 60.0]))
    data = np.deg2rad(np.linspace(0.0, 60.0, 600))
    excess = {}
    for kappa in (2.0, 2.5, 3.0):
        be = BiasExtension(90.0 * kappa, 90.0, 45.0)
        force = lambda t: be.crosshead_force(ns_true, t)  # noqa: E731
        excess[kappa] = 100.0 * (be.thesis_iterative(force, theta) / ns_true(theta) - 1.0)
        polynomial = 100.0 * (be.thesis_polynomial(data, force(data), theta) / ns_true(theta) - 1.0)
        np.testing.assert_allclose(polynomial, excess[kappa], atol=0.3)  # "agree closely" (thesis L5157)
    assert np.all((excess[2.0] > 1.5) & (excess[2.0] < 9.0))  # the digest's 2-8 % over 10-60 deg
    # this curve's figures, as computed by this test when it was written (stated in the docstring)
    np.testing.assert_allclose(excess[2.0], [1.94, 4.77, 6.52, 8.67], atol=0.01)
    assert np.all(excess[2.0] > excess[2.5]) and np.all(excess[2.5] > excess[3.0]) and np.all(excess[3.0] > 0)


# ---------------------------------------------------------------- round trips through files


ROUND_TRIP_RIGS = {
    "PF phi0 45": PictureFrame(145.0, 45.0),
    "PF phi0 30 (non-orthogonal)": PictureFrame(145.0, 30.0),
    "BE kappa 2": BiasExtension(180.0, 90.0, 45.0),
    "BE kappa 2.5": BiasExtension(225.0, 90.0, 45.0),
    "BE kappa 3": BiasExtension(270.0, 90.0, 45.0),
    "BE kappa 2 phi0 30": BiasExtension(242.0, 70.0, 30.0),
}


@pytest.mark.parametrize("label", list(ROUND_TRIP_RIGS))
def test_round_trip_recovers_the_curve_within_the_noise(tmp_path, label):
    rig = ROUND_TRIP_RIGS[label]
    max_deg = 45.0 if rig.phi0_deg == 30.0 else 60.0
    result = fitted(tmp_path, rig, rig_keys={}, fit=f'friction = "subtract"\nmax_angle_deg = {max_deg}')
    theta, ns = card_curve(result)
    assert np.rad2deg(theta[-1]) == pytest.approx(max_deg)
    error = np.abs(ns - ns_true(theta))
    assert np.all(error <= point_noise(rig, theta)), (label, error.max())
    record = result.doc["sheartest"]["positive"]
    assert record["friction_offset_n"][0] == pytest.approx(FRICTION_N, abs=0.5)
    assert record["residual_rms_n"][0] == pytest.approx(NOISE_N, rel=0.1)  # the fit leaves the noise
    assert load_material(_write_card(tmp_path, result)).curve("positive")[1][-1] == pytest.approx(ns[-1])


def _write_card(tmp_path, result):
    from uqdrape.material.cards import card_text

    path = tmp_path / "card.toml"
    path.write_text(card_text(result.doc), encoding="utf-8")
    return path


def test_friction_kept_starts_the_curve_at_the_jump(tmp_path):
    rig = PictureFrame(145.0, 45.0)
    result = fitted(tmp_path, rig, fit='friction = "keep"')
    theta, ns = card_curve(result)
    assert ns[0] == pytest.approx(FRICTION_N / (2e-3 * 145.0 * np.sqrt(0.5)), abs=point_noise(rig, 0.0))
    error = ns - ns_true(theta) - rig.shear_force(lambda t: FRICTION_N + 0 * t, theta)
    assert np.all(np.abs(error) <= point_noise(rig, theta))


@pytest.mark.parametrize("kappa", [2.0, 2.5, 3.0])
def test_picture_frame_and_bias_extension_of_one_material_give_one_card(tmp_path, kappa):
    pf_rig, be_rig = PictureFrame(145.0, 45.0), BiasExtension(90.0 * kappa, 90.0, 45.0)
    (tmp_path / "pf").mkdir()
    (tmp_path / "be").mkdir()
    theta_pf, pf = card_curve(fitted(tmp_path / "pf", pf_rig, seed=1))
    theta_be, be = card_curve(fitted(tmp_path / "be", be_rig, seed=2))
    np.testing.assert_array_equal(theta_pf, theta_be)
    # each within its own point noise of the truth, so within the sum of each other
    assert np.all(np.abs(pf - be) <= point_noise(pf_rig, theta_pf) + point_noise(be_rig, theta_pf))


def test_a_measured_angle_is_used_and_divergence_ends_the_valid_range(tmp_path):
    rig = BiasExtension(180.0, 90.0, 45.0)
    result = fitted(tmp_path, rig, measured=True, slip_from_deg=40.0)
    record = result.doc["sheartest"]["positive"]
    assert record["angle_source"] == ["measured"] and record["end_rule"] == ["divergence"]
    # slip of 0.5 mm/deg past 40°: kinematic θ runs ahead by 2° (the tolerance) within ~3° more
    assert 40.0 < record["valid_end_deg"][0] < 44.0
    theta, ns = card_curve(result)
    assert np.all(np.abs(ns - ns_true(theta)) <= point_noise(rig, theta))


def test_specimens_give_the_mean_card_and_the_sd_of_their_curves(tmp_path):
    rig = PictureFrame(145.0, 45.0)
    scales = np.random.default_rng(7).normal(1.0, 0.08, 5)  # specimen-to-specimen factors
    result = fitted(tmp_path, rig, scales=list(scales))
    theta, ns = card_curve(result)
    scatter = result.doc["scatter"]["positive"]
    assert scatter["specimens"] == 5 and scatter["angle_deg"] == result.doc["shear"]["positive"]["angle_deg"]
    noise = point_noise(rig, theta)
    assert np.all(np.abs(ns - scales.mean() * ns_true(theta)) <= noise)
    assert np.all(np.abs(np.asarray(scatter["ns_sd"]) - scales.std(ddof=1) * ns_true(theta)) <= noise)


def test_an_ncf_card_has_both_branches_from_the_tests_each_way(tmp_path):
    rng = np.random.default_rng(3)
    rig_pos, rig_neg = PictureFrame(145.0, 40.0), PictureFrame(145.0, 50.0)  # negative: tested at 90 − φ0
    write_specimen(tmp_path / "p.csv", rig_pos, rng)
    write_specimen(tmp_path / "n.csv", rig_neg, rng, scale=0.3, max_deg=40.0)
    path = write_rig(tmp_path / "rig.toml", "picture_frame", [("p.csv", "positive"), ("n.csv", "negative")],
                     fit="max_angle_deg = 35.0", side_mm=145.0, phi0_deg=40.0)
    result = fit_card(read_rig(path), "ncf", path.name)
    material = load_material(_write_card(tmp_path, result))
    assert not material.symmetric and material.phi0_deg == 40.0
    for branch, scale, rig in (("positive", 1.0, rig_pos), ("negative", 0.3, rig_neg)):
        angles, ns = material.curve(branch)
        theta = np.deg2rad(angles)
        friction = rig.shear_force(lambda t: FRICTION_N + 0 * t, theta)  # friction kept (the default)
        assert np.all(np.abs(ns - scale * ns_true(theta) - friction) <= point_noise(rig, theta)), branch


def test_unloading_rows_are_not_fitted(tmp_path):
    rig = PictureFrame(145.0, 45.0)
    path = write_specimen(tmp_path / "s0.csv", rig, np.random.default_rng(0))
    loaded = fit_card(read_rig(write_rig(tmp_path / "rig.toml", "picture_frame", [("s0.csv", "positive")],
                                         side_mm=145.0)), "x", "rig.toml").doc["shear"]
    rows = path.read_text(encoding="utf-8").splitlines()
    theta = np.deg2rad(np.linspace(62.0, 30.0, 200))  # unloading: half the force on the way back
    back = zip(0.5 * rig.crosshead_force(ns_true, theta), rig.displacement(theta))
    path.write_text("\n".join(rows + [f"{f:.6f},{d:.6f}" for f, d in back]) + "\n", encoding="utf-8")
    unloaded = fit_card(read_rig(tmp_path / "rig.toml"), "x", "rig.toml").doc["shear"]
    assert unloaded == loaded


@pytest.mark.parametrize("change, expect", [
    ("ns_sd = [1.0, -1.0, 2.0]", "scatter.positive.ns_sd = [1.0, -1.0, 2.0] is invalid: ns_sd must be >= 0"),
    ("ns_sd = [1.0, 2.0]", "ns_sd must be 3 numbers >= 0 (N/m), one per angle"),
    ("angle_deg = [0, 10, 20]", "angle_deg must be the angles of [shear.positive]"),
    ("specimens = 1", "scatter.positive.specimens = 1 is invalid: specimens must be an integer >= 2"),
    ("[scatter.negative]", "unknown key scatter.negative; valid keys in [scatter]: positive"),
])
def test_a_card_refuses_a_bad_scatter_table(change, expect):
    from uqdrape.material.cards import card_material

    shear = ["[shear.positive]", "angle_deg = [0, 10, 30]", "ns = [0, 5, 20]", "[scatter.positive]"]
    scatter = {"angle_deg": "[0, 10, 30]", "ns_sd": "[0.0, 1.0, 2.0]", "specimens": "3"}
    lines = shear + [f"{k} = {v}" for k, v in scatter.items()]
    assert card_material("\n".join(lines), "ok.toml").curve("positive")[1][-1] == 20.0
    key, _, value = change.partition(" = ")
    if value:
        scatter[key] = value
    lines = shear + [f"{k} = {v}" for k, v in scatter.items()] + ([] if value else [change])
    with pytest.raises(ValueError) as err:
        card_material("\n".join(lines), "bad.toml")
    assert str(err.value).startswith("bad.toml: ") and expect in str(err.value)


def test_kappa_below_2_warns(tmp_path):
    result = fitted(tmp_path, BiasExtension(162.0, 90.0, 45.0))  # κ = 1.8
    assert len(result.warnings) == 1 and "kappa = 1.8 < 2" in result.warnings[0]
    assert "Warning: " in result.doc["note"]


def test_the_command_writes_the_card_and_its_figure(tmp_path, capsys):
    rng = np.random.default_rng(5)
    rig = BiasExtension(225.0, 90.0, 45.0)
    for i in range(3):
        write_specimen(tmp_path / f"b{i}.csv", rig, rng, scale=1.0 + 0.05 * (i - 1))
    path = write_rig(tmp_path / "rig.toml", "bias_extension", [(f"b{i}.csv", "positive") for i in range(3)],
                     name="be_fabric", height_mm=225.0, width_mm=90.0)
    card = tmp_path / "out" / "be.toml"
    assert main(["materials", "fit", str(path), "--out", str(card), "--plot"]) == 0
    out = capsys.readouterr().out
    assert f"wrote {card}: be_fabric (positive: 3 specimens to 60 deg" in out
    assert card.with_suffix(".png").stat().st_size > 10_000
    material = load_material(card)
    assert material.name == "be_fabric" and material.locking_angle_deg == 60.0
    assert main(["materials", str(card)]) == 0


@pytest.fixture(scope="module")
def three_conventions(tmp_path_factory):
    """One noise-free picture-frame test of ns_true written three ways, crosshead F (N),
    F/L and F_s/L (N/m), each fitted: {convention: CardFit}."""
    folder = tmp_path_factory.mktemp("conventions")
    pf = PictureFrame(145.0, 45.0)
    theta = np.linspace(0.0, np.deg2rad(62.0), 600)
    force = pf.crosshead_force(ns_true, theta)
    columns = {"crosshead": force, "F/L": pf.normalised_force(force), "F_s/L": ns_true(theta)}
    cards = {}
    for i, (convention, values) in enumerate(columns.items()):
        rows = "\n".join(f"{v:.12g},{d:.12g}" for v, d in zip(values, pf.displacement(theta)))
        (folder / f"c{i}.csv").write_text(f"force_n,displacement_mm\n{rows}\n", encoding="utf-8")
        path = write_rig(folder / f"rig{i}.toml", "picture_frame", [(f"c{i}.csv", "positive")], side_mm=145.0,
                         force_convention=convention)
        cards[convention] = fit_card(read_rig(path), "synthetic", path.name)
    return cards


def test_a_force_column_already_normalised_gives_the_same_card(three_conventions):
    """F/L is the crosshead force over a constant L, so its card is the crosshead card;
    F_s/L is fitted as it is; all three are within 0.5 % + 0.05 N/m of the truth."""
    curves = {c: card_curve(r) for c, r in three_conventions.items()}
    theta, ns = curves["crosshead"]
    np.testing.assert_allclose(curves["F/L"][1], ns, rtol=1e-12)
    for convention, (angles, values) in curves.items():
        np.testing.assert_array_equal(angles, theta)
        np.testing.assert_allclose(values, ns_true(theta), rtol=5e-3, atol=0.05, err_msg=convention)
        record = three_conventions[convention].doc["sheartest"]
        assert record["force_convention"] == convention
        assert record["force_unit"] == ("N" if convention == "crosshead" else "N/m")
    assert three_conventions["F/L"].doc["sheartest"]["normalisation"].startswith("force column is F/L (N/m")
    assert "N_s = F / (2 L cos" in three_conventions["crosshead"].doc["sheartest"]["normalisation"]


def test_the_card_figure_states_the_convention(three_conventions, tmp_path, monkeypatch):
    monkeypatch.setattr(plot, "_save", lambda fig, path: fig)
    fig = plot.plot_sheartest(three_conventions["F/L"], tmp_path / "x.png")
    raw, points, card = fig.axes
    assert raw.get_ylabel() == "force column F/L (N/m)"
    assert points.get_ylabel() == card.get_ylabel() == "normalised shear force $N_s = F_s/L$ (N/m)"
    assert "force column: F/L; force column is F/L (N/m, Eq 3.16): N_s = (F/L) / (2 cos(phi0 - theta/2))" in \
        fig._suptitle.get_text()


@pytest.mark.parametrize("value", ['"N/mm"', '"f/l"', "1.0"])
def test_a_bad_force_convention_is_refused_in_one_line(tmp_path, value):
    write_specimen(tmp_path / "good.csv", PictureFrame(145.0, 45.0), np.random.default_rng(0))
    path = tmp_path / "rig.toml"
    path.write_text(f'test = "picture_frame"\nside_mm = 145.0\nforce_convention = {value}\n'
                    '[[specimen]]\nfile = "good.csv"\n', encoding="utf-8")
    with pytest.raises(ShearTestError) as err:
        read_rig(path)
    assert_one_line_error(str(err.value), file=path, key="force_convention", value=value,
                          valid=['"crosshead"', '"F/L"', '"F_s/L"'])


# ---------------------------------------------------------------- bad files: one line each


def _bad_case(tmp_path, case):
    """A rig file with one fault ``case``; returns (path, text the message must contain)."""
    rng = np.random.default_rng(0)
    good = write_specimen(tmp_path / "good.csv", PictureFrame(145.0, 45.0), rng)
    text = good.read_text(encoding="utf-8").splitlines()
    csv_name, keys, expect = "bad.csv", dict(side_mm=145.0), None
    if case == "missing column":
        (tmp_path / csv_name).write_text("\n".join(["load,displacement_mm", *text[2:]]), encoding="utf-8")
        expect = "bad.csv: the header (the first line that is not a # comment) has no column 'force_n' (force)"
    elif case == "another file":  # named by mistake, or by someone else's rig file: not echoed
        (tmp_path / csv_name).write_text("daemon:x:1:1:daemon:/usr/sbin:/usr/sbin/nologin\nsecret,1\n", encoding="utf-8")
        expect = "bad.csv: the header (the first line that is not a # comment) has no column 'force_n' (force)"
    elif case == "not a number":
        text[7] = "12.5,abc"
        (tmp_path / csv_name).write_text("\n".join(text), encoding="utf-8")
        expect = "bad.csv: line 8, column displacement_mm: expected a number"
    elif case == "not finite":
        text[9] = "nan,1.0"
        (tmp_path / csv_name).write_text("\n".join(text), encoding="utf-8")
        expect = "bad.csv: line 10, column force_n: expected a finite number, not inf or nan"
    elif case == "row length":
        text[5] += ",3.0"
        (tmp_path / csv_name).write_text("\n".join(text), encoding="utf-8")
        expect = "bad.csv: line 6 has 3 values, the header 2"
    elif case == "too few rows":
        (tmp_path / csv_name).write_text("\n".join(text[:12]), encoding="utf-8")
        expect = "bad.csv: 10 data rows; a fit needs at least 20"
    elif case == "beyond the frame":
        text[40] = "50.0,300.0"
        (tmp_path / csv_name).write_text("\n".join(text), encoding="utf-8")
        expect = "bad.csv: line 41, column displacement_mm: 300 mm is beyond the rig's geometric limit"
    elif case == "file not found":
        csv_name, expect = "absent.csv", 'specimen[0].file = "absent.csv" is invalid: file not found'
    elif case == "missing side":
        csv_name, keys, expect = "good.csv", {}, "side_mm is missing"
    elif case == "wrong dimension":
        csv_name, keys = "good.csv", dict(side_mm=145.0, height_mm=100.0)
        expect = "height_mm = 100.0 is invalid: height_mm is a bias-extension dimension"
    elif case == "unknown key":
        csv_name, keys, expect = "good.csv", dict(side_mm=145.0, sidee_mm=1.0), "unknown key sidee_mm"
    test = "picture_frame"
    if case == "kappa":
        csv_name, test, keys = "good.csv", "bias_extension", dict(height_mm=120.0, width_mm=90.0)
        expect = "specimen[0]: kappa = (height_mm/width_mm) tan(phi0) = 1.333 is invalid"
    return write_rig(tmp_path / "rig.toml", test, [(csv_name, "positive")], **keys), expect


BAD_CASES = ["missing column", "another file", "not a number", "not finite", "row length", "too few rows", "beyond the frame",
             "file not found", "missing side", "wrong dimension", "unknown key", "kappa"]


@pytest.mark.parametrize("case", BAD_CASES)
def test_a_bad_file_gives_one_line_naming_file_and_place(tmp_path, case, capsys):
    path, expect = _bad_case(tmp_path, case)
    with pytest.raises(ShearTestError) as err:
        fit_card(read_rig(path), "x", path.name)
    assert expect in str(err.value) and "\n" not in str(err.value)
    assert main(["materials", "fit", str(path), "--out", str(tmp_path / "c.toml")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and expect in lines[0]
    assert "nologin" not in lines[0] and "secret" not in lines[0]
    assert not (tmp_path / "c.toml").exists()


# ---------------------------------------------------------------- junk refused, not averaged in


@pytest.mark.parametrize("case, expect", [
    ("all zero", "the force does not rise with shear"),
    ("all negative", "the force does not rise with shear"),
    ("decreasing", "the force does not rise with shear"),
    ("angle as force", "[columns] force and angle both name column 'angle_deg'"),
    ("force as angle", "a shear angle of 90 deg or more"),
    ("knots 1e9", "knots must be an integer with 1 <= knots < 101"),
    ("step 1e-9", "step_deg must be a number >= 0.01"),
])
def test_a_specimen_that_is_no_shear_test_is_refused_not_averaged_into_the_card(tmp_path, capsys, case, expect):
    rng = np.random.default_rng(1)
    rig = PictureFrame(145.0, 45.0)
    write_specimen(tmp_path / "good.csv", rig, rng, measured=True)
    bad = write_specimen(tmp_path / "bad.csv", rig, rng, measured=True)
    lines = bad.read_text(encoding="utf-8").splitlines()
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[2:]])
    force = {"all zero": 0.0 * rows[:, 0], "all negative": -rows[:, 0] - 1.0,
             "decreasing": rows[::-1, 0]}.get(case, rows[:, 0])
    swapped = case == "force as angle"
    body = "\n".join(f"{a:.6f},{d:.6f},{f:.6f}" if swapped else f"{f:.6f},{d:.6f},{a:.6f}"
                     for f, d, a in zip(force, rows[:, 1], rows[:, 2]))
    bad.write_text(f"{lines[0]}\n{lines[1]}\n{body}\n", encoding="utf-8")
    fit = {"knots 1e9": "knots = 1000000000", "step 1e-9": "step_deg = 1e-9"}.get(case, "")
    extra = ['[columns]', 'force = "angle_deg"'] if case == "angle as force" else []
    path = write_rig(tmp_path / "rig.toml", "picture_frame", [("good.csv", "positive"), ("bad.csv", "positive")],
                     fit=fit, side_mm=145.0)
    if extra:
        path.write_text(path.read_text().replace("[[specimen]]", "\n".join(extra) + "\n[[specimen]]", 1))
    assert main(["materials", "fit", str(path), "--out", str(tmp_path / "c.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expect in err[0], err
    assert not (tmp_path / "c.toml").exists()
