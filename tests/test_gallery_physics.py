"""Physics checks of the gallery's flat-plate spacing studies (issue 5; thesis §5.3.3, Figs 5.15/5.16).

Reduced runs: the shipped studies (energy drape, FGE 106hd-like NCF, 5 mm spacing,
30 rings, segment lengths with cv 1.5 %) with 40 instead of 200 realisations.
"Fibre angle" in the thesis's Fig 5.16 is the inter-fibre angle 90 deg - shear, so its
sd is the sd of node shear. Measured quantity: the per-node ensemble sd of node shear
averaged over each ring k = max(|i|, |j|) (``uqdrape.stats.ring_sd``); "inner" is
rings 1-5, "outer" rings 25-29 (the boundary ring 30 is left out: its node shear
averages fewer cells). Seeds are the studies' own, so every number is deterministic;
with 40 realisations a ring average of node sds is good to a few per cent.
The sd is about each node's own mean; that mean is not zero (see the first test).

Measured (seeds 5151, 40 realisations): iid inner 1.1 deg, outer 3.6 deg (thesis: Normal
fit sd 11.04 deg over the whole plate); smooth field (squared-exponential, L = 100 mm):
inner 0.06 deg, outer 1.65 deg; rough Ornstein-Uhlenbeck sheet (exponential, L = 30 mm):
inner 1.0 deg, outer 5.8 deg -- correlation removes the cumulative artefact only when
neighbouring fibres stay alike, i.e. for a smooth field or lengths beyond a few cells.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.stats import spearmanr

from uqdrape.ensemble import drape_inputs, sampled_inputs
from uqdrape.stats import inner_outer_sd, ring_sd
from uqdrape.study import load_study

from golden import (
    PLATE_CORRELATED_MEAN_CELL_SHEAR_DEG,
    PLATE_IID_INNER_SD_DEG,
    PLATE_IID_MEAN_CELL_SHEAR_DEG,
    PLATE_IID_OUTER_SD_DEG,
)

STUDIES = Path(__file__).resolve().parent.parent / "studies"
REALIZATIONS = 40


def _reduced_run(name: str):
    """The study's first REALIZATIONS realisations as one batched drape (its own seed and inputs)."""
    study = load_study(STUDIES / f"{name}.toml")
    assert study.solver.mode == "energy" and study.fabric.spacing_mm == 5.0
    assert study.uncertainty.fields["spacing"].params["cv"] == 0.015
    r = np.arange(REALIZATIONS)
    return drape_inputs(study, r, sampled_inputs(study, r))


@pytest.fixture(scope="module")
def iid():
    return _reduced_run("plate-spacing")


@pytest.fixture(scope="module")
def correlated():
    return _reduced_run("plate-correlated-spacing")


def test_studies_differ_only_in_the_spacing_correlation():
    a, b = (load_study(STUDIES / f"{n}.toml").to_dict() for n in ("plate-spacing", "plate-correlated-spacing"))
    for d in (a, b):
        d.pop("study"), d.pop("output"), d.pop("report")
    sa, sb = a["uncertainty"].pop("spacing"), b["uncertainty"].pop("spacing")
    assert a == b
    assert (sa["correlation"], sb["correlation"], sb["length_mm"]) == ("iid", "squared_exponential", [100.0, 100.0])


def test_random_spacing_moves_the_mean_shear_into_the_compliant_branch(iid, correlated):
    for ds in (iid, correlated):
        assert (ds["status"] == 0).all()
        assert float(ds["converged"].mean()) >= 0.95
    # without noise the energy drape of a plate is unsheared ...
    study = load_study(STUDIES / "plate-spacing.toml")
    exact = drape_inputs(study, np.arange(1), {})
    assert float(abs(exact["cell_shear"]).max()) < 1e-9
    # ... with it, the minimiser shifts every realisation towards the NCF's soft negative
    # branch (N_s about 8x lower than positive): E[W(mean + noise)] is least below zero.
    # -4.7 deg (iid), -0.9 deg (smooth field, L = 100 mm: smaller mismatches), the same sign
    # in every realisation; the iid mean asserted to the minimiser's tolerance (1e-3 deg), the
    # smooth field's to 0.05 deg: its shallow energy lets the floating point of another CPU's
    # BLAS kernels move the seeded sample's mean (-0.8761 deg on AVX-512 machines, -0.8975 on
    # an AMD EPYC with OpenBLAS's Haswell kernels).
    for ds, mean, tol in ((iid, PLATE_IID_MEAN_CELL_SHEAR_DEG, 1e-3), (correlated, PLATE_CORRELATED_MEAN_CELL_SHEAR_DEG, 0.05)):
        per_realisation = ds["cell_shear"].mean(("cell_i", "cell_j"))
        assert float(per_realisation.mean()) == pytest.approx(mean, abs=tol)
        assert bool((per_realisation < 0).all())


def test_iid_spacing_fibre_angle_sd_is_degrees_not_tenths(iid):
    inner, outer = inner_outer_sd(iid)
    # thesis: sd 11.04 deg over the plate; this model, on this seeded sample of 40: 3.556 deg
    # at rings 25-29 (degrees, a third of the thesis's fit) and 1.099 deg at rings 1-5,
    # asserted to the minimiser's tolerance
    assert outer == pytest.approx(PLATE_IID_OUTER_SD_DEG, abs=1e-3)
    assert inner == pytest.approx(PLATE_IID_INNER_SD_DEG, abs=1e-3)


def test_iid_spacing_scatter_grows_with_distance_from_the_crossover(iid):
    per_ring = ring_sd(iid).values
    inner, outer = inner_outer_sd(iid)
    assert outer > 2.5 * inner, (inner, outer)
    # growth along the whole net, not only at its edge
    assert spearmanr(np.arange(1, per_ring.size), per_ring[:-1]).statistic > 0.95
    # a cumulative (random-walk) artefact: roughly sqrt(k), so sd(k)^2 / k stays within a factor ~3
    k = np.arange(1, per_ring.size)
    ratio = per_ring[:-1] ** 2 / k
    assert ratio.max() / ratio.min() < 3.5, ratio


def test_correlated_spacing_reduces_the_local_scatter(correlated, iid):
    # neighbouring segments of a smooth field are nearly equal, so a cell next to the
    # crossover is nearly a parallelogram: its shear scatter is much smaller than iid's
    near_corr = float(ring_sd(correlated).sel(ring=slice(1, 2)).mean())
    near_iid = float(ring_sd(iid).sel(ring=slice(1, 2)).mean())
    assert near_corr < 0.75 * near_iid, (near_corr, near_iid)


def test_smooth_correlated_spacing_reduces_the_growth_of_the_scatter(correlated, iid):
    ci, co = inner_outer_sd(correlated)
    ii, io = inner_outer_sd(iid)
    assert co < 0.75 * io, (co, io)
    assert co - ci < 0.75 * (io - ii), (ci, co, ii, io)


def test_rough_ou_sheet_spacing_grows_the_scatter_faster_than_iid(iid, tmp_path):
    # the same study with an Ornstein-Uhlenbeck sheet of 6 cells: errors add up along a
    # fibre but neighbouring fibres decorrelate within a cell, so the mismatch grows faster
    text = (STUDIES / "plate-correlated-spacing.toml").read_text()
    text = text.replace('"squared_exponential"', '"exponential"').replace("[100.0, 100.0]", "[30.0, 30.0]")
    (tmp_path / "ou.toml").write_text(text)
    study = load_study(tmp_path / "ou.toml")
    r = np.arange(REALIZATIONS)
    _, rough_outer = inner_outer_sd(drape_inputs(study, r, sampled_inputs(study, r)))
    assert rough_outer > 1.2 * inner_outer_sd(iid)[1]
