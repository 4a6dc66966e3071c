"""The registry of per-drape quantities of interest: one number per realisation (and per
blank-holder level of a sweep), used by sensitivity studies (the outputs they rank),
blank-holder designs (what their objectives are statistics of) and reports.

Names and units are ``uqdrape.schema.QOI_ATTRS`` (a study file names them); each is
computed here, once:

- ``max_abs_shear``        largest |node shear| over the valid nodes (degree)
- ``mean_shear_positive``  signed shear averaged along the max-shear lines of the i*j > 0
                           quadrants, nodes k = 1..k_max (degree; ``uqdrape.stats.line_scalars``)
- ``mean_shear_negative``  the same for the i*j < 0 quadrants (degree)
- ``asymmetry``            their sum: 0 for a mirrored pattern (degree)
- ``blankholder_energy``   blank-holder friction work U_BH of the finished net (J)
- ``locked_fraction``      share of the valid cells (finite cell shear) that are locked (-)
- ``any_locked``           1 if any node of the net is locked, else 0 (-)
- ``max_draw_in``          largest radial draw-in of the held edge (mm; ``uqdrape.drape.draw_in``)
- ``lock_margin``          largest cell shear from its zero-energy angle over its branch's locking
                           angle, max((g - g0) / lock+, (g0 - g) / lock-) (-): above 1 exactly where
                           a cell is locked (``Material.is_locked``), so P(any cell locked) is
                           P(lock_margin > 1) and, unlike ``any_locked``, it says how near a drape came

k_max is the largest line node valid in every realisation of the Dataset given (or the
``k_max`` passed), so all realisations average the same nodes (stored as the attribute
``k_max``).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ..drape import draw_in
from ..schema import QOI_ATTRS, SENSITIVITY_QOIS
from .lines import line_scalars

QOIS = tuple(QOI_ATTRS)

#: The QoIs that are max-shear line means -> their variable of ``line_scalars``.
_LINE_QOIS = {"mean_shear_positive": "plus_mean_shear", "mean_shear_negative": "minus_mean_shear",
              "asymmetry": "asymmetry"}
#: The other QoIs: name -> the quantity of a drape Dataset.
_NODE_QOIS = {
    "max_abs_shear": lambda ds: abs(ds["shear"]).max(["i", "j"]),
    "blankholder_energy": lambda ds: ds["energy_blankholder"],
    "locked_fraction": lambda ds: ds["cell_locked"].where(ds["cell_shear"].notnull()).mean(["cell_i", "cell_j"]),
    "any_locked": lambda ds: (ds["locked"] > 0).any(["i", "j"]).astype(float),
    "max_draw_in": lambda ds: draw_in(ds).max(["i", "j"]),
    "lock_margin": lambda ds: _lock_margin(ds),
}
assert set(_LINE_QOIS) | set(_NODE_QOIS) == set(QOIS), "every named QoI is computed here"


def _lock_margin(ds: xr.Dataset) -> xr.DataArray:
    """The ``lock_margin`` of every drape in ``ds`` (its locking angles from its attributes)."""
    rel = ds["cell_shear"] - ds["gamma0"]
    ratio = np.fmax(rel / ds.attrs["locking_angle_deg"], -rel / ds.attrs["locking_angle_neg_deg"])
    return ratio.max(["cell_i", "cell_j"])


def check_qois(qoi) -> tuple[str, ...]:
    """``qoi`` as a tuple if it is a non-empty sequence of distinct QoI names, else ValueError."""
    qoi = tuple(qoi)
    unknown = [q for q in qoi if q not in QOIS]
    if not qoi or unknown or len(set(qoi)) != len(qoi):
        raise ValueError(f"qoi={list(qoi)} must be distinct names from {', '.join(QOIS)}")
    return qoi


def realization_qois(ds: xr.Dataset, qoi=SENSITIVITY_QOIS, k_max: int | None = None) -> xr.Dataset:
    """The quantities ``qoi`` (names from ``QOIS``) of every drape in ``ds`` (a drape or
    ensemble Dataset, dims [blankholder_force,] realization, i, j, ...): one variable per
    QoI with the Dataset's dims but the node ones, CF units and long_name; loaded.
    ``k_max``: the last max-shear line node the line QoIs average (default: the largest
    valid in every realisation of ``ds``)."""
    qoi = check_qois(qoi)
    lines = line_scalars(ds, k_max) if set(_LINE_QOIS) & set(qoi) else None
    out = {}
    for name in qoi:
        value = lines[_LINE_QOIS[name]] if name in _LINE_QOIS else _NODE_QOIS[name](ds)
        out[name] = value.drop_attrs().assign_attrs(QOI_ATTRS[name])
    result = xr.Dataset(out).compute()
    if lines is not None:
        result.attrs["k_max"] = lines.attrs["k_max"]
    return result
