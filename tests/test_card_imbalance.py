"""The card family by mid-angle imbalance and its calibration from a forming trial (issue 38):
``uqdrape.material.imbalance``, the study key ``fabric.imbalance_Nm`` and
``uqdrape.symmetry.imbalance_bounds`` / ``gap_model``."""

from __future__ import annotations

import numpy as np
import pytest

from uqdrape.drape import drape
from uqdrape.geometry import NoseCone
from uqdrape.material import load_material
from uqdrape.material.imbalance import imbalance, with_imbalance
from uqdrape.material.model import MaterialError
from uqdrape.stats import line_scalars
from uqdrape.study import StudyError, load_study
from uqdrape.symmetry import gap_model, imbalance_bounds, quadrant_gaps

from conftest import assert_one_line_error, write_study

DERIVED = load_material("ebxhd936_derived")
LIKE = load_material("ebxhd936_like")


@pytest.mark.parametrize("card", [DERIVED, LIKE], ids=lambda c: c.name)
@pytest.mark.parametrize("value", [0.5, 5.0, 300.0])
def test_the_family_moves_dN30_and_keeps_the_rest(card, value):
    moved = with_imbalance(card, value)
    assert imbalance(moved) == pytest.approx(value, rel=1e-12)
    angles, ns = card.curve("positive")
    new_angles, new_ns = moved.curve("positive")
    np.testing.assert_array_equal(new_angles, angles)  # both cards have a point at 30 deg
    neg = np.array([dict(zip(*card.curve("negative")))[a] for a in angles])  # both cards: a point at each angle
    rho = value / imbalance(card)
    below = angles <= 30.0
    np.testing.assert_allclose(new_ns[below] - neg[below], rho * (ns[below] - neg[below]), rtol=1e-12, atol=1e-12)
    beyond = angles >= card.locking_angle_deg
    np.testing.assert_array_equal(new_ns[beyond], ns[beyond])  # the measured end is the card's
    for branch in ("negative",):
        np.testing.assert_array_equal(moved.curve(branch)[1], card.curve(branch)[1])
    assert (moved.locking_angle_deg, moved.locking_angle_neg_deg) == (card.locking_angle_deg, card.locking_angle_neg_deg)


def test_the_card_own_value_is_the_card_itself():
    assert with_imbalance(DERIVED, imbalance(DERIVED)) is DERIVED
    assert imbalance(DERIVED) == pytest.approx(6.683 - 0.032, abs=1e-12)  # the card's points at 30 deg


@pytest.mark.parametrize("card, value, words", [
    ("generic_woven", 5.0, "no positive imbalance"),
    ("ebxhd936_like", 0.0, "> 0"),
    ("ebxhd936_like", float("nan"), "> 0"),
])
def test_the_family_refuses_what_it_cannot_scale(card, value, words):
    with pytest.raises(MaterialError, match=words) as err:
        with_imbalance(load_material(card), value)
    assert err.value.key == "imbalance_Nm"


def test_a_study_drapes_the_moved_card(tmp_path):
    from uqdrape.ensemble import drape_inputs
    from uqdrape.workflow.help_text import describe_study

    sections = {"geometry": {"kind": "nose_cone", "radius": None}, "fabric": {"material": "ebxhd936_derived", "imbalance_Nm": 20.0},
                "solver": {"mode": "energy", "rings": 8}, "study": {"realizations": 1, "chunk_size": 1}}
    study = load_study(write_study(tmp_path, **sections))
    assert "dN(30 deg) = 20 N/m" in describe_study(study)
    got = drape_inputs(study, [0], {})
    want = drape(NoseCone(), 5.0, 8, mode="energy", material=with_imbalance(DERIVED, 20.0),
                 blankholder_force=[50.0], friction=0.2)
    np.testing.assert_array_equal(got["shear"].values, want["shear"].values)
    plain = drape(NoseCone(), 5.0, 8, mode="energy", material=DERIVED, blankholder_force=[50.0], friction=0.2)
    assert np.nanmax(np.abs(got["shear"].values - plain["shear"].values)) > 1.0


@pytest.mark.parametrize("material, value, words", [
    ("generic_woven", 5.0, ["no positive imbalance"]),
    ("ebxhd936_like", -3.0, ["> 0"]),
])
def test_a_bad_imbalance_in_a_study_is_one_line_naming_the_key(tmp_path, material, value, words):
    path = write_study(tmp_path, fabric={"material": material, "imbalance_Nm": value})
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key="fabric.imbalance_Nm", valid=words)


# -- the symmetrising statements as an interval ------------------------------------------------------------------

SURFACE, SPACING, RINGS = NoseCone(), 5.0, 20


def _ratio(value, force, friction):
    kw = {"friction": friction, "blankholder_model": "radial"}
    k_max = quadrant_gaps(SURFACE, SPACING, RINGS, DERIVED, [0.0], None, kw)[1]
    gaps = quadrant_gaps(SURFACE, SPACING, RINGS, with_imbalance(DERIVED, value), [0.0, force], k_max, kw)[0]
    return gaps[1] / gaps[0]


def test_the_interval_edges_are_where_the_gap_falls_to_ten_percent():
    b = imbalance_bounds(SURFACE, SPACING, RINGS, DERIVED, asymmetric_at=(252,), symmetric_at=(378,),
                         friction=0.2, blankholder_model="radial")
    assert 1.0 < b.lower < b.upper < 100.0
    assert _ratio(b.upper, 378.0, 0.2) == pytest.approx(0.1, abs=2e-4)
    assert _ratio(b.lower, 252.0, 0.2) == pytest.approx(0.1, abs=2e-4)
    assert _ratio(b.upper * 1.05, 378.0, 0.2) > 0.1 > _ratio(b.upper / 1.05, 378.0, 0.2)


def test_the_interval_depends_on_friction_times_force_only():
    """The blank-holder energy is mu F times a slip: 252 N at mu 0.3 is 378 N at mu 0.2."""
    a = imbalance_bounds(SURFACE, SPACING, RINGS, DERIVED, symmetric_at=(378,), friction=0.2,
                         blankholder_model="radial")
    b = imbalance_bounds(SURFACE, SPACING, RINGS, DERIVED, asymmetric_at=(252,), friction=0.3,
                         blankholder_model="radial")
    assert a.lower is None and b.upper is None
    assert b.lower == pytest.approx(a.upper, rel=2e-3)


def test_contradicting_statements_are_refused():
    with pytest.raises(ValueError, match="contradict"):
        imbalance_bounds(SURFACE, SPACING, RINGS, DERIVED, symmetric_at=(126,), asymmetric_at=(378,),
                         friction=0.2, blankholder_model="radial")


# -- the synthetic round trip ----------------------------------------------------------------------------------

def test_the_trial_posterior_covers_a_known_imbalance():
    """Trials formed with dN(30) = 5 N/m (one part per force, its own zero-angle scatter, each
    gap read to 0.5 deg) calibrated back: at least 34 of 40 95 % intervals cover the truth
    (the 1 % lower quantile of Binomial(40, 0.95)), and each is far narrower than the prior."""
    forces, truth, read_sd, trials, rings = (0.0, 126.0, 252.0, 378.0), 5.0, 0.5, 40, 12
    kw = {"friction": 0.2, "blankholder_model": "radial"}
    model = gap_model(SURFACE, SPACING, rings, DERIVED, forces, zero_angle_sd_deg=2.0, realizations=8,
                      grid=(1.0, 100.0), points=13, **kw)
    rng = np.random.default_rng(2007)
    k_max = quadrant_gaps(SURFACE, SPACING, rings, DERIVED, [0.0], None, kw)[1]
    parts = drape(SURFACE, SPACING, rings, mode="energy", material=with_imbalance(DERIVED, truth),
                  blankholder_force=np.tile(forces, trials),
                  gamma0=rng.normal(0.0, 2.0, (trials * len(forces), 2 * rings, 2 * rings)), **kw)
    gaps = -line_scalars(parts, k_max)["asymmetry"].values.reshape(trials, len(forces))
    posts = [model.posterior(g + rng.normal(0.0, read_sd, len(forces)), read_sd) for g in gaps]
    covered = sum(p.interval[0] <= truth <= p.interval[1] for p in posts)
    assert covered >= 34, covered
    assert max(p.interval[1] / p.interval[0] for p in posts) < 3.0  # the prior spans a factor 100
    for p in posts:
        mass = np.sum(0.5 * (p.density[1:] + p.density[:-1]) * np.diff(np.log(p.grid)))
        assert mass == pytest.approx(1.0, rel=1e-12)


def test_a_trial_needs_one_gap_per_force():
    model = gap_model(SURFACE, SPACING, 6, DERIVED, (0.0, 378.0), grid=(1.0, 10.0), points=2, friction=0.2)
    with pytest.raises(ValueError, match="one finite gap"):
        model.posterior([1.0], 0.5)
    with pytest.raises(ValueError, match="sd_deg > 0"):
        model.posterior([1.0, 0.5], 0.0)
