"""Tests of uqdrape.symmetry.symmetrising_force on a small nose-cone net (fast)."""

import numpy as np
import pytest

from uqdrape.drape import drape
from uqdrape.geometry import build
from uqdrape.material import load_material
from uqdrape.stats import line_scalars
from uqdrape.symmetry import symmetrising_force

SPACING, RINGS = 10.0, 6


@pytest.fixture(scope="module")
def setup():
    return build("nose_cone"), load_material("ebxhd936_derived")


@pytest.fixture(scope="module")
def found(setup):
    nose, material = setup
    return symmetrising_force(nose, SPACING, RINGS, material, fraction=0.25, rtol=0.5, friction=0.2)


def test_bracket_holds_the_target_and_is_as_tight_as_asked(found):
    assert found.reached and found.gap0 > 10.0
    lo, hi = found.bracket
    assert found.gap_at(lo) > found.target >= found.gap_at(hi)
    assert hi / lo - 1.0 <= 0.5 and lo <= found.force <= hi
    assert found.target == pytest.approx(0.25 * found.gap0, rel=1e-12)
    assert {0.0, 126.0, 252.0, 378.0} <= set(found.forces)
    assert "falls to 0.25 x that" in found.describe()


def test_gaps_are_the_line_scalar_asymmetry_of_a_plain_drape(setup, found):
    nose, material = setup
    ds = drape(nose, SPACING, RINGS, mode="energy", material=material, blankholder_force=[0.0, 252.0], friction=0.2)
    gap = -line_scalars(ds, found.k_max)["asymmetry"].values
    np.testing.assert_allclose(gap, [found.gap_at(0.0), found.gap_at(252.0)], rtol=0, atol=1e-9)


def test_without_friction_the_blank_holder_cannot_symmetrise(setup):
    """friction reaches drape() unchanged: at mu = 0 the force does nothing, the gap stays."""
    nose, material = setup
    r = symmetrising_force(nose, SPACING, RINGS, material, forces=(100.0,), f_max=400.0, friction=0.0)
    assert not r.reached and r.force is None and r.bracket == (400.0, None)
    assert np.ptp(r.gaps) < 1e-9
    assert "not reached below F_max = 400 N" in r.describe()


def test_bad_arguments(setup):
    nose, material = setup
    with pytest.raises(ValueError, match="fraction must lie in"):
        symmetrising_force(nose, SPACING, RINGS, material, fraction=1.5)
