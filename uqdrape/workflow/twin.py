"""The fixed-parameter twin of a hierarchical run, and the widening measured from the two.

A hierarchical ensemble (``[uncertainty.zero_angle] sd_dof`` and/or ``length_log_sd``)
draws each realisation's zero-angle sd and correlation lengths from their calibration's
uncertainty. How much wider that makes the limits is not a function of the drawn values
alone (the drape responds more than linearly to the sd, and a length enters through the
field's shape), so ``uqdrape run`` measures it: unless ``[report] fixed_twin = false``,
it also drapes the *fixed-parameter twin* (:func:`fixed_twin`), the same study with the
draws removed (sd and lengths at their estimates) and the same seed and realisations,
into ``<run>/fixed`` (a store: ``<URL>/fixed``), through the same resumable engine.
Each realisation's stream draws the sd's and the lengths' normals after every other
number (``uqdrape.ensemble.inputs``), so the two ensembles share every field noise and
factor and differ only by the drawn parameters. The twin costs as many drapes as the run
(a target run's twin matches its final count).

The report of the run (:func:`hierarchical_summary`) then states, over the nodes that
move (fixed-run sd above ``MOVING`` of its largest, every force level pooled), the
median and 5-95 % of the per-node ratios hierarchical / fixed of the shear sd and of the
width of the 5-95 % band (the report's own ``node_statistics`` quantiles), and the share
of the variance from the small measurement, 1 - var_fixed / var_hier. Without a complete
twin of the same realisations it says the widening was not measured and how to measure it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..ensemble import at, open_ensemble, read_manifest
from ..ensemble.inputs import realization_length_mm, realization_sd_deg
from ..schema import FORCE, REALIZATION, by_force
from ..study import identity

#: The twin's folder inside the run's (a store: its URL's last part).
TWIN = "fixed"
#: A node moves if its fixed-twin shear sd is above this share of the largest at its level.
MOVING = 0.01
#: The study keys the twin removes: what the hierarchical run draws per realisation.
DRAWN_KEYS = ("sd_dof", "length_log_sd")
#: The report's rows: the drawn parameters, the measurement (or why it was not made) and
#: what it measured.
DRAWN_SD = "zero-angle sd drawn per realisation (deg)"
DRAWN_LENGTHS = "zero-angle lengths drawn per realisation (x the estimate)"
MEASURED = "widening measured against the fixed-parameter twin"
SD_WIDER = "node-shear sd wider than the twin's by"
BAND_WIDER = "5-95 % band wider than the twin's by"
SHARE = "share of the variance from the small measurement"


def twin_location(out):
    """Where the fixed twin of the run in ``out`` (a folder or a store's URL) is draped."""
    return at(out).child(TWIN).target


def fixed_twin(study, realizations: int, out):
    """The fixed-parameter twin of hierarchical ``study`` whose run in ``out`` holds
    ``realizations``: its drawn keys removed, named ``<name>-fixed``, that many
    realisations (no target), draped into :func:`twin_location`."""
    field = dataclasses.replace(study.uncertainty.fields["zero_angle"], **dict.fromkeys(DRAWN_KEYS))
    uncertainty = dataclasses.replace(study.uncertainty, fields={**study.uncertainty.fields, "zero_angle": field})
    return dataclasses.replace(study, name=f"{study.name}-{TWIN}", realizations=realizations, target=None,
                               max_realizations=None, uncertainty=uncertainty, output_dir=twin_location(out),
                               report=dataclasses.replace(study.report, fixed_twin=None))


def _untwinned(record: dict) -> dict:
    """A run's study identity without the name, the drawn keys and ``fixed_twin``: equal for
    a hierarchical run and its twin."""
    doc = identity(record)
    doc["study"].pop("name", None)
    for key in DRAWN_KEYS:
        doc.get("uncertainty", {}).get("zero_angle", {}).pop(key, None)
    return doc


def _open_twin(out, realizations) -> tuple:
    """(the twin's ensemble at the run's realisations, None) or (None, why it cannot be used)."""
    where = twin_location(out)
    try:
        hier, twin = read_manifest(out) or {"study": {}}, read_manifest(where)
        if twin is None:
            off = hier["study"].get("report", {}).get("fixed_twin") is False
            return None, "[report] fixed_twin = false" if off else f"{TWIN}/ holds no run"
        if not hier["study"] or _untwinned(twin["study"]) != _untwinned(hier["study"]):
            return None, f"{TWIN}/ holds the run of another study"
        ds = open_ensemble(where)
    except (OSError, ValueError) as err:  # FileNotFoundError (an incomplete twin) is an OSError
        return None, f"{TWIN}/ cannot be read ({err})"
    held = np.isin(realizations, ds[REALIZATION].values)
    if not held.all():
        ds.close()
        return None, f"{TWIN}/ holds {int(held.sum())} of the run's {held.size} realisations"
    return ds.sel({REALIZATION: realizations}).assign_attrs(twin_wall_time_s=twin.get("wall_time_s")), None


def widening(hier, fixed) -> dict:
    """The measured widening of ensemble ``hier`` against its twin ``fixed`` (Datasets with
    ``shear`` over the same realisations): ``nodes`` (node values that move, every force
    level), and the (5 %, median, 95 %) over them of ``sd`` and ``band`` (ratios
    hierarchical / fixed of the shear sd and of the 5-95 % band width) and ``share``
    (1 - var_fixed / var_hier); only ``nodes`` (0) if none moves."""
    from ..stats import node_statistics

    h, f = (node_statistics(by_force(ds), quantiles=(0.05, 0.95)) for ds in (hier, fixed))
    band_h, band_f = (s["quantile_value"].sel(quantile=0.95) - s["quantile_value"].sel(quantile=0.05) for s in (h, f))
    sd_h, sd_f = h["sd"], f["sd"]
    largest = sd_f.max([d for d in sd_f.dims if d in ("i", "j")])
    moving = (sd_f > MOVING * largest) & (sd_h > 0) & (band_f > 0)
    ratio, band = (sd_h / sd_f).values[moving.values], (band_h / band_f).values[moving.values]
    if not ratio.size:
        return {"nodes": 0}
    spread = [0.05, 0.5, 0.95]
    return {"nodes": ratio.size, "sd": tuple(np.quantile(ratio, spread)), "band": tuple(np.quantile(band, spread)),
            "share": tuple(np.quantile(1.0 - ratio ** -2.0, spread))}


def _row(low: float, mid: float, high: float, what: str) -> tuple:
    """(value, how) of a report row: the median of per-node ``what`` in % and its 5-95 %."""
    return f"{100 * mid:.1f} %", f"median over the nodes (5-95 %: {100 * low:.1f} to {100 * high:.1f} %) of {what}"


def hierarchical_summary(study, ds, out) -> dict | None:
    """The report's statement of a hierarchical run ``ds`` in ``out`` (a folder or a
    store's URL), rows of (value, how): the drawn sds and lengths, and the widening
    measured against its fixed twin (see the module docstring), or why it was not
    measured; None for a study that draws neither."""
    field = study.uncertainty.fields.get("zero_angle")
    if field is None or all(getattr(field, key) is None for key in DRAWN_KEYS):
        return None
    r = np.asarray(ds[REALIZATION].values, dtype=int)
    whole = dataclasses.replace(study, realizations=max(study.realizations, int(r.max()) + 1))
    said = {}
    if field.sd_dof is not None:
        low, mid, high = np.quantile(realization_sd_deg(whole, r), [0.05, 0.5, 0.95])
        said[DRAWN_SD] = (f"{mid:.3g}", f"median (5-95 %: {low:.3g} to {high:.3g}) of sd_deg "
                          f"{field.params['sd_deg']:.4g} x sqrt(m / chi2_m), m = sd_dof = {field.sd_dof:g}")
    if field.length_log_sd is not None:
        low, mid, high = np.quantile(realization_length_mm(whole, r)[:, 0] / field.length_mm[0], [0.05, 0.5, 0.95])
        said[DRAWN_LENGTHS] = (f"x {mid:.3g}", f"median (5-95 %: x {low:.3g} to x {high:.3g}) of exp(s z), "
                               f"s = length_log_sd = {field.length_log_sd:g}, both lengths")
    twin, why = _open_twin(out, r)
    if twin is not None:
        with twin:
            measured, took = widening(ds, twin), twin.attrs["twin_wall_time_s"]
        if not measured["nodes"]:
            twin, why = None, "no node moves in the twin"
    if twin is None:
        said[MEASURED] = ("not measured", f"{why}; run the study again with [report] fixed_twin = true (the "
                                          f"default) to drape its twin into {TWIN}/ (the run's own drapes are kept)")
        return said
    levels = by_force(ds).sizes[FORCE]
    said[MEASURED] = (f"{r.size} realisations, {measured['nodes']:,} nodes"
                      + (f" x levels (of {levels} force levels)" if levels > 1 else ""),
                      f"its twin in {TWIN}/: the same realisations with sd and lengths at the estimates"
                      + (f" ({took:g} s of drapes)" if took is not None else "")
                      + f"; over the nodes that move (twin sd above {100 * MOVING:g} % of its largest)")
    (a, b, c), (d, e, f), share = measured["sd"], measured["band"], measured["share"]
    said[SD_WIDER] = _row(a - 1, b - 1, c - 1, "the hierarchical shear sd / the twin's, per node, - 1")
    said[BAND_WIDER] = _row(d - 1, e - 1, f - 1, "the hierarchical 5-95 % band's width / the twin's, per node, - 1")
    said[SHARE] = _row(*share, "1 - var twin / var hierarchical, per node; the rest: the fabric")
    return said
