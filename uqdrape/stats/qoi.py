"""Scalar quantities of interest of each drape, the outputs a sensitivity study ranks.

Names are :data:`QOIS`, the choices of a study's ``[sensitivity] qoi``. Each is one
number per realisation (and per blank-holder level of a sweep):

- ``max_abs_shear``        largest |node shear| over the valid nodes (degree)
- ``mean_shear_positive``  signed shear averaged along the max-shear lines of the i*j > 0
                           quadrants, nodes k = 1..k_max (degree; ``uqdrape.stats.line_scalars``)
- ``mean_shear_negative``  the same for the i*j < 0 quadrants (degree)
- ``asymmetry``            their sum: 0 for a mirrored pattern (degree)
- ``blankholder_energy``   blank-holder friction work U_BH of the finished net (J)
- ``locked_fraction``      share of the valid cells (finite cell shear) that are locked (-)

k_max is the largest line node valid in every realisation of the Dataset given, so all
realisations average the same nodes (stored as the attribute ``k_max``).
"""

from __future__ import annotations

import xarray as xr

from .lines import line_scalars

#: (units, long_name) of each quantity of interest.
QOI_ATTRS = {
    "max_abs_shear": ("degree", "largest absolute node shear"),
    "mean_shear_positive": ("degree", "mean shear along the max-shear lines of the i*j > 0 quadrants"),
    "mean_shear_negative": ("degree", "mean shear along the max-shear lines of the i*j < 0 quadrants"),
    "asymmetry": ("degree", "mean_shear_positive + mean_shear_negative (0 when mirrored)"),
    "blankholder_energy": ("J", "blank-holder friction energy"),
    "locked_fraction": ("1", "fraction of the valid cells that are locked"),
}
QOIS = tuple(QOI_ATTRS)

#: The QoIs that are max-shear line means -> their variable of ``line_scalars``.
_LINE_QOIS = {"mean_shear_positive": "plus_mean_shear", "mean_shear_negative": "minus_mean_shear",
              "asymmetry": "asymmetry"}


def realization_qois(ds: xr.Dataset, qoi=QOIS) -> xr.Dataset:
    """The quantities ``qoi`` (names from ``QOIS``) of every drape in ``ds`` (a drape or
    ensemble Dataset, dims [blankholder_force,] realization, i, j, ...): one variable per
    QoI with the Dataset's dims but the node ones, CF units and long_name; loaded."""
    qoi = tuple(qoi)
    unknown = [q for q in qoi if q not in QOIS]
    if not qoi or unknown or len(set(qoi)) != len(qoi):
        raise ValueError(f"qoi={list(qoi)} must be distinct names from {', '.join(QOIS)}")
    out = {}
    lines = line_scalars(ds) if set(_LINE_QOIS) & set(qoi) else None
    for name in qoi:
        if name in _LINE_QOIS:
            value = lines[_LINE_QOIS[name]]
        elif name == "max_abs_shear":
            value = abs(ds["shear"]).max(["i", "j"])
        elif name == "blankholder_energy":
            value = ds["energy_blankholder"]
        else:
            locked = ds["cell_locked"].where(ds["cell_shear"].notnull())
            value = locked.mean(["cell_i", "cell_j"])
        units, long_name = QOI_ATTRS[name]
        out[name] = value.drop_attrs().assign_attrs(units=units, long_name=long_name)
    result = xr.Dataset(out).compute()
    if lines is not None:
        result.attrs["k_max"] = lines.attrs["k_max"]
    return result
