"""A card's specimen scatter as an uncertain input (issue 24): [uncertainty.card] gives
each realisation a score z, its card N_s = max(mean + z sd, 0) at every angle."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import assert_one_line_error, write_study
from uqdrape.cli import main as cli
from uqdrape.ensemble import open_ensemble, sampled_inputs
from uqdrape.files import toml_text
from uqdrape.material import load_material
from uqdrape.material.scatter import card_scatter, scattered
from uqdrape.sensitivity import study_problem
from uqdrape.study import StudyError, load_study

CARD = {"dist": "normal", "mean": 0.0, "sd": 1.0}


def _card(folder, relative_sd=0.15):
    """ebxhd936_like's curves with a specimen sd of ``relative_sd`` of N_s at every angle."""
    base = load_material("ebxhd936_like")
    doc = {"name": "scattered", "locking_angle_deg": base.locking_angle_deg,
           "locking_angle_neg_deg": base.locking_angle_neg_deg, "shear": {}, "scatter": {}}
    for branch in ("positive", "negative"):
        angles, ns = base.curve(branch)
        doc["shear"][branch] = {"angle_deg": angles.tolist(), "ns": ns.tolist()}
        doc["scatter"][branch] = {"angle_deg": angles.tolist(), "ns_sd": (relative_sd * ns).tolist(), "specimens": 5}
    path = folder / "scattered.toml"
    path.write_text(toml_text(doc), encoding="utf-8")
    return path


def _study(folder, **sections):
    card = _card(folder)
    base = {"fabric": {"material": card.name}, "solver": {"mode": "energy", "rings": 10}, "uncertainty": {"card": CARD}}
    return write_study(folder, **{**base, **sections})


def test_a_realisations_card_is_the_mean_moved_by_z_sd_and_clipped_at_zero(tmp_path):
    card = _card(tmp_path, relative_sd=0.4)
    base, scatter = load_material(card), card_scatter(card)
    for z in (-3.0, -0.5, 0.0, 1.7):
        varied = scattered(base, scatter, z)
        for branch in ("positive", "negative"):
            angles, ns = base.curve(branch)
            got_angles, got = varied.curve(branch)
            np.testing.assert_array_equal(got_angles, angles)
            np.testing.assert_array_equal(got, np.maximum(ns + z * scatter[branch], 0.0))
        assert (varied.locking_angle_deg, varied.locking_angle_neg_deg) == (base.locking_angle_deg,
                                                                             base.locking_angle_neg_deg)


def test_the_sampled_curves_have_the_specimens_mean_and_sd_at_every_angle(tmp_path):
    study = load_study(_study(tmp_path, study={"realizations": 4000}))
    z = sampled_inputs(study, np.arange(4000))["card"]
    base, scatter = load_material(study.fabric.material), card_scatter(study.fabric.material)
    angles, mean = base.curve("positive")
    curves = np.maximum(mean + z[:, None] * scatter["positive"], 0.0)  # what scattered() drapes, every angle
    n, sd = len(z), scatter["positive"]
    # estimates within 4 standard errors: the mean's sd / sqrt(n), the sd's sd / sqrt(2 n)
    assert np.all(np.abs(curves.mean(0) - mean) <= 4 * sd / np.sqrt(n) + 1e-12)
    assert np.all(np.abs(curves.std(0, ddof=1) - sd) <= 4 * sd / np.sqrt(2 * n) + 1e-12)
    assert scattered(base, scatter, z[0]).curve("positive")[1] == pytest.approx(curves[0], rel=1e-15)


def test_a_proportional_card_scatter_moves_the_drape_only_against_the_blankholder(tmp_path):
    """N_s scaled by (1 + 0.15 z) scales the whole shear energy: with no blank-holder force the
    drape barely moves (only the small bending term is not scaled), with 300 N it does."""
    path = _study(tmp_path, study={"realizations": 8, "chunk_size": 8},
                  process={"blankholder_force_N": [0.0, 300.0]}, geometry={"radius": 100.0})
    assert cli(["run", str(path), "--scheduler", "synchronous", "-q", "--no-report"]) == 0
    with open_ensemble(tmp_path / "tiny") as ds:
        sd = ds["shear"].std("realization").max(["i", "j"]).values
        assert ds["card"].attrs["units"] == "1" and np.ptp(ds["card"].values) > 1.0
    assert sd[1] > 0.05 and sd[0] < 0.05 * sd[1], sd  # measured: 0.0014 and 0.087 deg


def test_the_card_scatter_is_one_sensitivity_factor(tmp_path):
    study = load_study(_study(tmp_path, uncertainty={"card": CARD, "friction": {"dist": "uniform",
                                                                               "bounds": [0.1, 0.3]}}))
    problem = study_problem(study)
    assert problem["names"][:2] == ["friction", "card"] and problem["dists"][1] == "norm"


@pytest.mark.parametrize("sections, valid", [
    ({"solver": {"mode": "geodesic"}}, ['mode = "energy"']),
    ({"fabric": {"material": "ebxhd936_like"}}, ["no [scatter] table", "uqdrape materials fit"]),
])
def test_a_card_factor_without_what_it_needs_is_refused(tmp_path, sections, valid):
    _card(tmp_path)
    path = write_study(tmp_path, **{"fabric": {"material": "scattered.toml"}, "solver": {"mode": "energy"},
                                    "uncertainty": {"card": CARD}, **sections})
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert err.value.key == "uncertainty.card"
    assert_one_line_error(str(err.value), file=path, key="uncertainty.card", valid=valid)


def test_a_woven_cards_scatter_does_not_move_a_hemisphere_drape():
    """On a symmetric (woven) card the hemisphere's ring turns are zero by symmetry, so no
    card scales them; an NCF's two branches break the symmetry and the card moves the drape
    (README: what card scatter does to the shear)."""
    from uqdrape.drape import drape
    from uqdrape.geometry import build
    from uqdrape.material.model import Material

    surf, angles = build("hemisphere", radius=100.0), np.arange(0.0, 61.0, 2.0)
    ns = 34.0 * angles / 8.0
    woven = Material("woven", angles, ns, locking_angle_deg=55.0)
    ncf = Material("ncf", angles, ns, angles, 0.3 * ns, locking_angle_deg=55.0, locking_angle_neg_deg=55.0)
    sd = {}
    for card in (woven, ncf):
        cards = [scattered(card, {"positive": 0.15 * ns, "negative": 0.0 * ns}, z) for z in (-1.5, 1.5)]
        ds = drape(surf, 5.0, 6, mode="energy", material=cards, blankholder_force=np.full(2, 300.0), friction=0.2)
        shear = ds["shear"].values
        sd[card.name] = np.nanmax(np.abs(shear[1] - shear[0]))
    assert sd["woven"] < 1e-9 and sd["ncf"] > 1e-3, sd
