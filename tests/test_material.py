"""Tests of uqdrape.material: energy density, cell energy, locking, cards, CSV, plot."""

import numpy as np
import pytest
from scipy.integrate import quad

from uqdrape.material import Material, available_materials, load_material, plot_material
from uqdrape.material.model import LOCK_STIFFNESS_PER_RAD

from golden import EBXHD936_LIKE_NS_60_DEG_N_PER_M

SHIPPED = ["ebxhd936_like", "fge106hd_like", "generic_woven", "twintex3_like"]
#: cards derived from the shipped fabric architectures (tests/test_architecture.py)
DERIVED = ["ebxhd936_derived", "fge106hd_1p65mm_derived", "fge106hd_5mm_derived", "fge106hd_derived"]


def constant(ns=100.0, end_deg=60.0, **props):
    return Material.from_curves("const", [0.0, end_deg], [ns, ns], **props)


@pytest.mark.parametrize("phi0_deg", [45.0, 30.0, 40.0])
def test_constant_force_matches_closed_form(phi0_deg):
    mat = constant(phi0_deg=phi0_deg, end_deg=55.0)
    phi0 = np.deg2rad(phi0_deg)
    g = np.deg2rad(np.linspace(0.5, 55.0, 40))
    exact_pos = 100.0 * (np.cos(2 * phi0 - g) - np.cos(2 * phi0)) / np.sin(2 * phi0)
    # negative branch: the inter-tow angle opens to 2φ0 + |γ|
    exact_neg = 100.0 * (np.cos(2 * phi0) - np.cos(2 * phi0 + g)) / np.sin(2 * phi0)
    np.testing.assert_allclose(mat.energy_density(g), exact_pos, rtol=1e-6)
    np.testing.assert_allclose(mat.energy_density(-g), exact_neg, rtol=1e-6)
    if phi0_deg == 45.0:
        np.testing.assert_allclose(mat.energy_density(g), 100.0 * np.sin(g), rtol=1e-6)


def test_thesis_worked_example():
    # notes §1.6: constant 100 N/m to 30° gives W = 50 J/m², U_cell(5 mm × 5 mm) = 1.25 mJ
    mat = constant(100.0, end_deg=30.0)
    g = np.deg2rad(30.0)
    assert mat.energy_density(g) == pytest.approx(50.0, rel=1e-9)
    assert mat.cell_energy(g, 5.0, 5.0) == pytest.approx(1.25e-3, rel=1e-9)
    assert not mat.is_locked(g)


def test_card_curve_matches_quadrature():
    mat = load_material("ebxhd936_like")
    for branch, sense in (("positive", 1.0), ("negative", -1.0)):
        for deg in (7.3, 33.0, 58.0):
            t = np.deg2rad(deg)
            ref, _ = quad(lambda u: abs(float(mat.shear_force(sense * u))) * np.cos(u), 0.0, t, limit=200)
            assert mat.energy_density(sense * t) == pytest.approx(ref, rel=1e-7), (branch, deg)


@pytest.mark.parametrize("name", SHIPPED)
def test_energy_invariants(name):
    mat = load_material(name)
    assert mat.energy_density(0.0) == 0.0
    for sense, lock in ((1.0, mat.locking_angle_deg), (-1.0, mat.locking_angle_neg_deg)):
        g = sense * np.deg2rad(np.linspace(0.0, lock + 5.0, 500))
        w = mat.energy_density(g)
        assert np.all(w >= 0.0)
        assert np.all(np.diff(w) > 0.0)  # strictly monotone in |γ| (N_s > 0 away from 0)


@pytest.mark.parametrize("name", ["ebxhd936_like", "twintex3_like"])
def test_derivative_matches_finite_differences(name):
    mat = load_material(name)
    lock_p, lock_n = mat.locking_angle_deg, mat.locking_angle_neg_deg
    deg = np.concatenate([np.linspace(-lock_n - 4, -0.5, 37), np.linspace(0.5, lock_p + 4, 37)])
    deg = deg[np.abs(np.abs(deg) - np.where(deg > 0, lock_p, lock_n)) > 0.05]  # away from the kink in W''
    g = np.deg2rad(deg)
    h = 1e-6
    fd = (mat.energy_density(g + h) - mat.energy_density(g - h)) / (2 * h)
    np.testing.assert_allclose(mat.denergy_density(g), fd, rtol=1e-5, atol=1e-6)
    # dW/dγ = N_s·sin(2φ0 − γ)/sin 2φ0 inside the data, with φ0 = 45°: N_s·cos γ
    inside = ~mat.is_locked(g)
    np.testing.assert_allclose(mat.denergy_density(g[inside]),
                               mat.shear_force(g[inside]) * np.cos(g[inside]), rtol=1e-9)


def test_locking_wall_is_continuous_and_steep():
    mat = load_material("ebxhd936_like")
    lock = np.deg2rad(mat.locking_angle_deg)
    eps = 1e-12
    assert mat.energy_density(lock + eps) == pytest.approx(mat.energy_density(lock - eps), rel=1e-8)
    assert mat.denergy_density(lock + eps) == pytest.approx(mat.denergy_density(lock - eps), rel=1e-6)
    k = LOCK_STIFFNESS_PER_RAD * 1097.3  # largest N_s of the card
    d = np.deg2rad(2.0)
    expected = mat.energy_density(lock) + mat.denergy_density(lock - eps) * d + 0.5 * k * d**2
    assert mat.energy_density(lock + d) == pytest.approx(expected, rel=1e-9)
    # two degrees past locking costs more than the whole positive branch up to locking
    assert mat.energy_density(lock + d) > 2 * mat.energy_density(lock)


def test_locked_flags_per_branch():
    mat = load_material("ebxhd936_like")  # +60° / −65°
    deg = np.array([[0.0, 59.9, 60.1, 64.0], [-64.9, -65.1, -60.1, np.nan]])
    expected = np.array([[False, False, True, True], [False, True, False, False]])
    np.testing.assert_array_equal(mat.is_locked(np.deg2rad(deg)), expected)
    assert mat.is_locked(np.deg2rad(deg)).shape == (2, 4)
    assert np.isnan(mat.energy_density(np.nan))


def test_ebxhd_asymmetry_and_scales():
    mat = load_material("ebxhd936_like")
    g = np.deg2rad(30.0)
    assert mat.energy_density(g) > 5 * mat.energy_density(-g)
    ns_60 = mat.shear_force(np.deg2rad(60.0))
    assert 700 <= ns_60 <= 1200  # the thesis's scale: "high hundreds of N/m by 60 deg"
    assert ns_60 == pytest.approx(EBXHD936_LIKE_NS_60_DEG_N_PER_M, rel=1e-12)  # the card's own curve
    neg = mat.curve("negative")[1]
    assert neg.max() <= 140.0
    fge = load_material("fge106hd_like")
    assert fge.curve("positive")[1].max() == pytest.approx(350.0)
    assert fge.curve("negative")[1].max() < 60.0


def test_cell_energy_broadcasts_and_offsets():
    mat = load_material("generic_woven")
    g = np.deg2rad(np.array([[10.0, 20.0], [30.0, -5.0]]))
    s1 = np.array([5.0, 4.0])
    u = mat.cell_energy(g, s1, 5.0, gamma0_rad=np.deg2rad(5.0))
    assert u.shape == (2, 2)
    expected = s1 * 5.0 * 1e-6 * mat.energy_density(g - np.deg2rad(5.0))
    np.testing.assert_allclose(u, expected, rtol=1e-12)
    assert mat.cell_energy(np.deg2rad(5.0), 5.0, 5.0, gamma0_rad=np.deg2rad(5.0)) == 0.0
    # a ±30 fabric has an initial cell area s1·s2·sin 60°
    mat30 = constant(phi0_deg=30.0, end_deg=55.0)
    assert mat30.cell_energy(0.3, 5.0, 5.0) == pytest.approx(25e-6 * np.sin(np.deg2rad(60)) * mat30.energy_density(0.3))


def test_woven_is_symmetric():
    mat = load_material("twintex3_like")
    g = np.deg2rad(np.linspace(-45, 45, 31))
    np.testing.assert_allclose(mat.energy_density(g), mat.energy_density(-g), rtol=1e-12)
    np.testing.assert_array_equal(mat.is_locked(g), mat.is_locked(-g))
    assert mat.symmetric and mat.locking_angle_neg_deg == 42.0


def test_shipped_cards_load():
    assert available_materials() == sorted(SHIPPED + DERIVED)
    for name in SHIPPED:
        mat = load_material(name)
        assert mat.name == name
        assert "not measured data" in mat.note.lower()
        assert 0 < mat.bending_stiffness < 1e-4
        for branch in ("positive", "negative"):
            angles, ns = mat.curve(branch)
            assert angles[0] == 0.0 and ns[0] == 0.0
            assert np.all(np.diff(ns) > 0.0)
    assert load_material("ebxhd936_like").stitch_direction_deg == 45.0
    assert load_material("twintex3_like").stitch_direction_deg is None


def test_csv_round_trip(tmp_path):
    ref = load_material("ebxhd936_like")
    a_pos, n_pos = ref.curve("positive")
    a_neg, n_neg = ref.curve("negative")
    grid = a_pos  # both branches on the 0..65° grid
    n_neg = np.interp(grid, a_neg, n_neg)
    path = tmp_path / "my_ncf.csv"
    rows = "\n".join(f"{a:g},{p:.10g},{n:.10g}" for a, p, n in zip(grid, n_pos, n_neg))
    path.write_text("# measured somewhere\nangle_deg, ns_positive, ns_negative\n" + rows + "\n")
    mat = load_material(path)
    assert mat.name == "my_ncf"
    assert mat.locking_angle_deg == 65.0 and mat.locking_angle_neg_deg == 65.0
    g = np.deg2rad(np.array([-50.0, -10.0, 10.0, 50.0]))
    # same curves; only the tabulation grid differs (positive branch tabulated to 65° here, 60° in the card)
    np.testing.assert_allclose(mat.energy_density(g), ref.energy_density(g), rtol=1e-9)

    # a TOML card pointing to the CSV, with its own properties; a one-branch CSV is symmetric
    sym = tmp_path / "sym.csv"
    sym.write_text("angle_deg,ns_positive\n0,0\n20,10\n40,60\n")
    card = tmp_path / "card.toml"
    card.write_text('name = "mine"\nlocking_angle_deg = 35.0\n[shear]\ncsv = "sym.csv"\n')
    mat = load_material(str(card))
    assert mat.name == "mine" and mat.symmetric
    assert mat.locking_angle_deg == mat.locking_angle_neg_deg == 35.0
    assert mat.is_locked(np.deg2rad(36.0)) and mat.is_locked(np.deg2rad(-36.0))


@pytest.mark.parametrize(
    "filename, text, message",
    [
        ("a.csv", "angle_deg,ns_negative\n0,0\n10,5\n", "first line that is not a # comment must be the header angle_deg,ns_positive"),
        ("b.csv", "angle_deg,ns_positive\n0,0\n10,abc\n", "data row 3, column ns_positive: expected a number"),
        ("c.csv", "angle_deg,ns_positive\n0,0\n20,5\n10,8\n", "angles must be strictly increasing, got 20 then 10"),
        ("d.csv", "angle_deg,ns_positive,ns_negative\n0,0,0\n10,5,-3\n",
         "N_s must be >= 0 (give the magnitude for the negative branch), got -3"),
        ("e.csv", "angle_deg,ns_positive\n5,0\n10,5\n", "the first angle must be 0 deg"),
        ("f.toml", "name = 'x'\n[shear.positive]\nangle_deg = [0, 10]\n", "shear.positive.ns is missing"),
        ("g.toml", "locking_deg = 40\n[shear.positive]\nangle_deg = [0, 10]\nns = [0, 1]\n", "unknown key locking_deg"),
        ("h.toml", "locking_angle_deg = 95\n[shear.positive]\nangle_deg = [0, 100]\nns = [0, 1]\n",
         "locking_angle_deg must be below 90 deg"),
        ("i.toml", "locking_angle_deg = 50\n[shear.positive]\nangle_deg = [0, 40]\nns = [0, 1]\n",
         "locking_angle_deg must be in (0, 40] deg"),
        ("j.toml", "stitch_direction_deg = 0.0\n[shear.positive]\nangle_deg = [0, 40]\nns = [0, 1]\n",
         "stitch_direction_deg must bisect +fibre1 and +fibre2"),
        ("k.toml", "phi0_deg = 'wide'\n[shear.positive]\nangle_deg = [0, 40]\nns = [0, 1]\n",
         'phi0_deg = "wide" is invalid: phi0_deg must be a finite number'),
    ],
)
def test_bad_files_raise_with_file_and_problem(tmp_path, filename, text, message):
    path = tmp_path / filename
    path.write_text(text)
    with pytest.raises(ValueError) as err:
        load_material(path)
    assert str(path) in str(err.value)
    assert message in str(err.value)


POSITIVE = "[shear.positive]\nangle_deg = [0, 40]\nns = [0, 1]\n"


@pytest.mark.parametrize("text, key, words", [
    ("locking_deg = 40\n" + POSITIVE, "locking_deg",
     ["unknown key locking_deg; valid keys in the file's top level: name, description, note, phi0_deg"]),
    ("locking_angle_deg = 50\n" + POSITIVE, "locking_angle_deg",
     ["locking_angle_deg = 50 is invalid", "must be in (0, 40] deg"]),
    ("[shear.positive]\nangle_deg = [0, 20, 10]\nns = [0, 1, 2]\n", "shear.positive",
     ["shear.positive = { angle_deg = [0, 20, 10], ns = [0, 1, 2] } is invalid", "strictly increasing"]),
    (POSITIVE + "[shear.negative]\nangle_deg = [0, 40]\nns = [0, true]\n", "shear.negative.ns",
     ["shear.negative.ns = [0, true] is invalid: ns must be a list of numbers"]),
    ("[shear]\npos = 1\n", "shear.pos", ["valid keys in [shear]: csv, positive, negative"]),
    ('[shear]\ncsv = "nope.csv"\n', "shear.csv", ['shear.csv = "nope.csv" is invalid: file not found']),
    ('[shear]\ncsv = "c.csv"\n', "shear.csv", ['shear.csv = "c.csv" is invalid', "strictly increasing"]),
    ('name = "x"\n', "shear", ["shear is missing"]),
    ("a = " + "[" * 3000 + "]" * 3000, None, ["nested more than"]),
])
def test_card_errors_carry_file_key_and_what_is_valid(tmp_path, text, key, words):
    from uqdrape.files import FileFormatError

    (tmp_path / "c.csv").write_text("angle_deg,ns_positive\n0,0\n20,5\n10,8\n")
    path = tmp_path / "card.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(FileFormatError) as err:
        load_material(path)
    message = str(err.value)
    assert message.startswith(f"{path}: ") and "\n" not in message and err.value.key == key
    assert all(w in message for w in words), message


def test_utf16_card_is_read(tmp_path):
    path = tmp_path / "card.toml"
    path.write_text('description = "φ card"\n' + POSITIVE, encoding="utf-16")
    assert load_material(path).description == "φ card"


def test_unknown_name_and_missing_file(tmp_path):
    with pytest.raises(ValueError, match="unknown material 'ebx936'.*ebxhd936_derived, ebxhd936_like, fge106hd_1p65mm_derived, "
                       "fge106hd_5mm_derived, fge106hd_derived, fge106hd_like, generic_woven, twintex3_like"):
        load_material("ebx936")
    with pytest.raises(ValueError, match="material file not found"):
        load_material(tmp_path / "nope.toml")


def test_plot_writes_png(tmp_path):
    out = plot_material(load_material("ebxhd936_like"), tmp_path / "ebx.png")
    data = out.read_bytes()
    assert len(data) > 10_000 and data[:8] == b"\x89PNG\r\n\x1a\n"


def _bitwise(a, b) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and np.array_equal(a.view(np.int64), b.view(np.int64))


def test_the_cards_pchip_and_simpson_are_scipys_bitwise():
    """A card is tabulated without scipy (issue 41: ``uqdrape validate`` imports none of
    scipy.interpolate or scipy.integrate); its monotone cubic and cumulative Simpson are
    scipy's PchipInterpolator(extrapolate=False) and cumulative_simpson(initial=0) to the
    bit: for every shipped card's branches and for curves with flat, falling, two-point
    and irregular stretches, at and between the points, at the ends and outside (NaN)."""
    from scipy.integrate import cumulative_simpson
    from scipy.interpolate import PchipInterpolator

    from uqdrape.material import model

    rng = np.random.default_rng(41)
    curves = []
    for name in available_materials():
        card = load_material(name)
        curves += [(b.angles_rad, b.ns) for b in (card._pos, card._neg)]
    for k in range(200):
        n = 2 + k % 12
        x = np.deg2rad(np.concatenate([[0.0], np.cumsum(rng.uniform(0.05, 8.0, n - 1))]))
        y = [rng.uniform(0, 500, n), np.round(rng.uniform(0, 2, n)), np.cumsum(rng.uniform(0, 50, n)),
             rng.normal(0, 30, n)][k % 4]
        curves.append((x, y))
    for x, y in curves:
        ours, scipys = model._Pchip(x, y), PchipInterpolator(x, y, extrapolate=False)
        at = np.concatenate([x, np.linspace(0.0, x[-1], 301), rng.uniform(-0.1, x[-1] + 0.1, 50),
                             [-1e-12, x[-1] * (1 + 1e-15), np.nan, np.inf]])
        assert _bitwise(ours(at), scipys(at))
        assert _bitwise(ours(0.5 * x[-1]), scipys(0.5 * x[-1]))  # a scalar gives a 0-d array
        for points in (3, 4, 17, model.TABLE_POINTS):
            grid = np.linspace(0.0, x[-1], points)
            dw = ours(grid) * np.sin(0.5 * np.pi - grid)
            assert _bitwise(model._cumulative_simpson(dw, grid), cumulative_simpson(dw, x=grid, initial=0.0))
