"""Morris index maps vectorised over nodes (issue 29): the indices of thousands of output
columns from one computation equal SALib's ``morris.analyze`` called per column, for a
grouped problem shaped like a study's (scalar factors + one random field of many KL
variables); and a sensitivity run keeps its analysis for a resume."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from SALib.analyze import morris as salib_morris

from uqdrape.sensitivity import analyze_map, make_problem, sample
from uqdrape.stochastic import normal, uniform
from uqdrape.workflow import MAPS_FILE, run_study

from conftest import write_study

#: The variables the test analyses per column with SALib itself.
CHECKED = (0, 1, 2, 57, 150, 299)


def field_problem(modes=200):
    """Three scalar factors and a field of ``modes`` KL variables (four groups)."""
    return make_problem({"a": uniform(0.0, 1.0), "b": normal(0.0, 1.0), "c": uniform(0.0, 1.0)}, {"f": modes})


def node_outputs(X, n_nodes=300, seed=0):
    """Outputs of ``n_nodes`` nodes: each a different smooth mix of the factors and the
    field's modes, node 1 a constant |effect| (linear in a), node 2 driven by b alone."""
    rng = np.random.default_rng(seed)
    w = rng.normal(size=(X.shape[1], n_nodes))
    Y = np.sin(X @ w / 3.0) + X[:, [0]] * X[:, [1]] ** 2
    Y[:, 1] = 4.0 * X[:, 0]
    Y[:, 2] = np.tanh(X[:, 1])
    return Y


def test_morris_maps_equal_salib_per_node():
    p = field_problem()
    X, _ = sample(p, "morris", base_samples=20, seed=5)
    Y = node_outputs(X)
    seen = []
    maps = analyze_map(p, X, xr.DataArray(Y, dims=("realization", "node")), method="morris", seed=9,
                       progress=seen.append)
    assert sum(seen) == Y.shape[1]
    for col in CHECKED:
        S = salib_morris.analyze(dict(p), X, Y[:, col].copy(), num_levels=4, seed=9)
        scale = np.max(S["mu_star"])  # round-off is relative to the effects' size (a zero sd is ~1e-16)
        for name in ("mu", "mu_star", "mu_star_conf", "sigma"):
            expected = np.asarray(S[name], dtype=float)
            np.testing.assert_allclose(maps[name].isel(node=col).values, expected, rtol=1e-12, atol=1e-12 * scale,
                                       err_msg=f"{name}, node {col}")
    # the field's sigma is undefined (a group of 200), a's effect at node 1 the same in every trajectory
    assert np.isnan(maps.sigma.sel(factor="f")).all()
    assert maps.mu_star_conf.sel(factor="a").isel(node=1) < 1e-12


def test_a_sample_whose_variables_move_twice_is_refused():
    p = field_problem(4)
    X, _ = sample(p, "morris", base_samples=10, seed=1)
    X[1, 0] = X[0, 0] + 0.5  # variable a now also moves at a step that is not its own
    with pytest.raises(ValueError, match="not a Morris trajectory sample"):
        analyze_map(p, X, xr.DataArray(node_outputs(X, 3), dims=("realization", "node")), method="morris", seed=0)


@pytest.mark.slow  # ~20 s: 60 small energy drapes and the Morris analysis, twice
def test_a_resumed_morris_run_keeps_its_analysis(tmp_path, capsys):
    path = write_study(tmp_path, "screen", study={"realizations": 8, "chunk_size": 64},
                       geometry={"kind": "nose_cone", "radius": None}, fabric={"material": "ebxhd936_like"},
                       process={"blankholder_force_N": 0.0}, solver={"mode": "energy", "rings": 4},
                       uncertainty={"zero_angle": {"sd_deg": 5.0},
                                    "friction": {"dist": "uniform", "bounds": [0.15, 0.3]}},
                       sensitivity={"method": "morris", "base_samples": 20})
    out = run_study(path, workers=1, progress=False)
    stamp = (out / MAPS_FILE).stat().st_mtime_ns
    run_study(path, workers=1, progress=True)
    assert (out / MAPS_FILE).stat().st_mtime_ns == stamp
    assert "indices already analysed" in capsys.readouterr().err
    run_study(path, workers=1, progress=False, resume=False)  # a fresh run analyses again
    assert (out / MAPS_FILE).stat().st_mtime_ns != stamp
