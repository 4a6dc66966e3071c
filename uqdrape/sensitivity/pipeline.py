"""One way through a sensitivity study: sample -> evaluate -> analyze."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
import xarray as xr

from .analysis import analyze
from .design import sample


def run_sensitivity(problem: Mapping, evaluate: Callable[[np.ndarray], np.ndarray], *,
                    base_samples: int, method: str = "sobol", seed: int,
                    qoi_names: Sequence[str] | None = None, conf_level: float = 0.95,
                    num_resamples: int = 100) -> xr.Dataset:
    """Sample the design, evaluate ``evaluate(X) -> Y`` once, analyse every QoI.

    X is (n_evaluations, num_vars) in physical units; Y must be (n_evaluations,) or
    (n_evaluations, n_qoi). ``seed`` drives both the design and the bootstrap. Returns
    the Dataset of ``analyze`` with the design metadata of ``sample`` in its attributes.
    """
    X, meta = sample(problem, method, base_samples=base_samples, seed=seed)
    Y = np.asarray(evaluate(X), dtype=float)
    if Y.ndim not in (1, 2) or Y.shape[0] != X.shape[0]:
        raise ValueError(
            f"evaluate returned shape {Y.shape}; expected ({X.shape[0]},) or ({X.shape[0]}, n_qoi)"
        )
    ds = analyze(problem, X, Y, method=method, qoi_names=qoi_names, conf_level=conf_level,
                 seed=seed, num_resamples=num_resamples)
    ds.attrs.update(meta)
    return ds
