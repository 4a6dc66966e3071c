"""A study's rare exceedance events as limit states in standard normal space, for
``uqdrape.reliability``: P(QoI >= threshold) of a drape whose random inputs are the
standard normals U.

U's columns are the study's design variables (``uqdrape.ensemble.design_variables``): a
scalar factor's u = Phi(U) (then its own ``ppf``), a random field's truncated KL modes
as they are (``kl_retained`` of its variance). A batch of rows is one batched drape.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr

from ..ensemble import design_variables, drape_inputs, inputs_from_design
from ..material import load_material
from ..stats import realization_qois


def drape_limit_state(study, qoi: str, threshold: float, force: float | None = None):
    """(g, d) for P(``qoi`` >= ``threshold``) of ``study``'s drapes at blank-holder level
    ``force`` (N; None: the only one): g(U) = threshold - qoi of the drapes of the rows
    of U (n, d), so failure is g <= 0. A line QoI averages the max-shear line nodes valid
    in the nominal drape (U = 0), the same nodes in every batch."""
    names = design_variables(study)
    factors = len(study.uncertainty.factors)
    surface, material = study.geometry.build_mould(), load_material(study.fabric.material)

    def values(U, k_max=None):
        X = np.array(U, dtype=float, ndmin=2)
        X[:, :factors] = ndtr(X[:, :factors])
        ds = drape_inputs(study, np.arange(len(X)), inputs_from_design(study, X), force=force, surface=surface,
                          material=material)
        return realization_qois(ds, [qoi], k_max)

    k_max = values(np.zeros((1, len(names)))).attrs.get("k_max")

    def g(U):
        return threshold - values(U, k_max)[qoi].values

    return g, len(names)
