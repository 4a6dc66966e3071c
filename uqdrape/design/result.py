"""A finished design as one Dataset (``design.nc``): every evaluated design with its
statistics, the optimum with its bootstrap interval, the validation sample's estimates
and the result in plain words."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import xarray as xr

from .estimators import DRAW_IN, RARE, STATISTICS, excess, objective_value, penalised, statistics
from .evaluate import EVALUATIONS, Evaluator
from .optimise import Result

#: The design run's output file.
DESIGN_FILE = "design.nc"
#: Realisation resamples of the force interval and of the margin's interval.
BOOTSTRAP = 400


def _resampled(values: list, n: int, seed: int) -> dict:
    """Per-drape quantities of designs (a list of per-design dicts, the same realisations)
    under ``n`` common realisation resamples: name -> (n, design, R)."""
    R = len(next(iter(values[0].values())))
    idx = np.random.default_rng(seed).integers(0, R, size=(n, 1, R))
    return {name: np.stack([v[name] for v in values])[np.arange(len(values))[None, :, None], idx]
            for name in values[0]}


def result_dataset(result: Result, evaluate: Evaluator) -> xr.Dataset:
    """Every evaluated design with its statistics, and the result, as one Dataset."""
    prob, spec = result.prob, result.prob.spec
    confidence = spec.confidence
    rows = list(evaluate.order)
    stats = [evaluate.statistics([x], s)[0] for s, _, x in rows]
    X = np.array([x for _, _, x in rows])
    settings = [prob.settings(x) for x in X]
    data = {
        "x": (("evaluation", "variable"), X, {"long_name": "design vector (N; friction -)"}),
        "total_force": ("evaluation", [s[0] for s in settings], {"units": "N", "long_name": "total blank-holder force"}),
        "friction": ("evaluation", [s[2] for s in settings], {"units": "1", "long_name": "blank-holder friction"}),
        "sample": ("evaluation", [s for s, _, _ in rows], {"long_name": "design (common random numbers) or validation"}),
        "key": ("evaluation", [k for _, k, _ in rows], {"long_name": f"record in {EVALUATIONS}/"}),
        "objective": ("evaluation", [objective_value(s, spec) for s in stats],
                      {"long_name": f"objective: {spec.statistic} of {spec.objective}"
                                    + (f", distance from {spec.target:g}" if spec.target is not None else "")}),
        "feasible": ("evaluation", [int(excess(s, spec) == 0) for s in stats],
                     {"units": "1", "long_name": "keeps the draw-in limit and the rare constraint (1) or not (0)"}),
    }
    if spec.rare is not None:
        records = [evaluate([x], s)[0].attrs for s, _, x in rows]
        for part, i in (("probability", 0), ("lower", 1), ("upper", 2)):
            data[f"rare_{part}"] = ("evaluation", [s[RARE][i] for s in stats], {
                "units": "1", "long_name": f"P({spec.rare.qoi} >= {spec.rare.threshold:g})"
                                           + (" estimate" if i == 0 else f" {part} ({confidence:.0%}, log-normal)")})
        data["rare_cov"] = ("evaluation", [r["rare_cov"] for r in records], {"units": "1", "long_name": "its CoV"})
        data["rare_drapes"] = ("evaluation", [int(r["rare_drapes"]) for r in records],
                               {"units": "1", "long_name": "drapes of its estimate"})
        data["rare_method"] = ("evaluation", [str(r["rare_method"]) for r in records],
                               {"long_name": "importance (at the most probable point), subset (simulation), montecarlo "
                                             "(not rare) or below (no failure reached: P is a bound)"})
        data["rare_note"] = ("evaluation", [str(r.get("rare_note", "")) for r in records],
                             {"long_name": "why the estimate is above its target CoV (then not feasible) or a bound"})
    units_of = {"p_locked": "1", DRAW_IN: "mm"}
    for name in STATISTICS:
        units = units_of.get(name, "degree")
        for i, part in enumerate(("", "_lower", "_upper")):
            data[name + part] = ("evaluation", [s[name][i] for s in stats],
                                 {"units": units, "long_name": f"{name}{part or ' estimate'} ({confidence:.0%})"})
    ds = xr.Dataset(data, coords={"variable": list(prob.names)})
    val = {role: evaluate([x], "validation")[0] for role, x in result.validation.items()}
    for role in val:
        rec = val[role]
        nv = rec["node_valid"].where(rec["node_valid"] > 0)
        ds[f"{role}_node_p_locked"] = (rec["node_locked"] / nv).assign_attrs(
            units="1", long_name=f"P(node locked), {role} design, validation sample")
        ds[f"{role}_node_x"] = (rec["node_x"] / nv).assign_attrs(units="mm")
        ds[f"{role}_node_y"] = (rec["node_y"] / nv).assign_attrs(units="mm")
    design_X = np.array([x for s, _, x in rows if s == "design"])
    resampled = _resampled(evaluate.values(design_X), BOOTSTRAP, prob.study.seed)
    boot_stats = statistics({k: resampled[k] for k in {spec.objective, DRAW_IN}}, confidence)
    if spec.rare is not None:  # a design's rare estimate is its own, not a resample of the realisations
        rare = np.array([s[RARE] for s in evaluate.statistics(design_X)])
        boot_stats[RARE] = tuple(np.broadcast_to(column, (BOOTSTRAP, len(design_X))) for column in rare.T)
    boot = penalised(boot_stats, spec)
    best = design_X[np.argmin(boot, axis=1)]
    opt_stats = evaluate.statistics([result.optimum])[0][spec.objective]
    val_stats = {role: evaluate.statistics([x], "validation")[0] for role, x in result.validation.items()}
    inside = opt_stats[1] <= val_stats["optimum"][spec.objective][0] <= opt_stats[2]
    ds.attrs.update(
        study_name=prob.study.name, objective=spec.objective, statistic=spec.statistic,
        target=spec.target if spec.target is not None else "none", confidence=confidence,
        max_draw_in_mm=spec.max_draw_in_mm or "none",
        rare=json.dumps(dataclasses.asdict(spec.rare)) if spec.rare is not None else "none",
        variables=list(prob.names), bounds=json.dumps(prob.bounds), budget_N=spec.budget_N or "none",
        k_max=result.k_max, optimiser=result.message, design_seed=prob.study.seed,
        design_realizations=prob.study.realizations, validation_seed=prob.validation.seed,
        validation_realizations=prob.validation.realizations, drapes_this_run=int(evaluate.drapes),
        drapes_total=int(sum(prob.study.realizations if s == "design" else prob.validation.realizations
                             for s, _, _ in rows) + (ds["rare_drapes"].sum() if spec.rare is not None else 0)),
        optimum=list(result.optimum), optimum_lower=list(np.quantile(best, 0.025, axis=0)),
        optimum_upper=list(np.quantile(best, 0.975, axis=0)), optimum_interval=(
            f"2.5-97.5 % of the best evaluated design over {BOOTSTRAP} realisation resamples"),
        optimum_estimate=list(opt_stats), baseline=list(prob.baseline),
        validation=json.dumps({role: {"x": list(x), "estimate": list(val_stats[role][spec.objective]),
                                      "draw_in": list(val_stats[role][DRAW_IN]),
                                      **({"rare": list(val_stats[role][RARE])} if spec.rare is not None else {})}
                               for role, x in result.validation.items()}),
        validated=int(inside), study_json=json.dumps(prob.study.to_dict()),
    )
    if "uniform" in result.validation:
        ds.attrs["margin"] = json.dumps(_margin(result, evaluate))
    ds.attrs["summary"] = summary_text(ds)
    return ds


def _margin(result: Result, evaluate: Evaluator) -> dict:
    """Uniform minus sector objective estimate at equal total, on both samples, with a
    paired bootstrap interval (the same realisations under both designs)."""
    spec = result.prob.spec
    out = {}
    for sample in ("design", "validation"):
        values = evaluate.values([result.validation["uniform"], result.optimum], sample)
        resampled = _resampled(values, BOOTSTRAP, result.prob.study.seed + 1)
        boot = statistics({spec.objective: resampled[spec.objective]}, spec.confidence)[spec.objective][0]
        d = boot[:, 0] - boot[:, 1]
        est = [statistics(v, spec.confidence)[spec.objective][0] for v in values]
        c = spec.confidence
        out[sample] = [float(est[0] - est[1]), float(np.quantile(d, (1 - c) / 2)), float(np.quantile(d, (1 + c) / 2))]
    return out


def summary_text(ds: xr.Dataset) -> str:
    """The result in plain words, e.g. "F = 290 N [260, 330]: p_locked 0.02 [0.01, 0.04] vs 0.31 at 126 N"."""
    names = list(ds.attrs["variables"])
    opt, lo, hi = (np.atleast_1d(ds.attrs[k]) for k in ("optimum", "optimum_lower", "optimum_upper"))
    val = json.loads(ds.attrs["validation"])
    name = ds.attrs["objective"]
    fmt = "{:.3g}"

    def stat(e):
        return f"{fmt.format(e[0])} [{fmt.format(e[1])}, {fmt.format(e[2])}]"

    design = ", ".join(f"{'F' if n == 'force' else n} = {o:.0f}{'' if n == 'friction' else ' N'} [{a:.0f}, {b:.0f}]"
                       if n != "friction" else f"friction {o:.3f} [{a:.3f}, {b:.3f}]"
                       for n, o, a, b in zip(names, opt, lo, hi))
    base = val["baseline"]
    n_forces = sum(n != "friction" for n in names)
    base_total = sum(base["x"][:n_forces])
    text = (f"{design}: {name} {stat(val['optimum']['estimate'])} vs {stat(base['estimate'])} at the baseline "
            f"{base_total:.0f} N (validation sample, {ds.attrs['validation_realizations']} drapes, "
            f"{ds.attrs['confidence']:.0%} limits). ")
    opt_est = ds.attrs["optimum_estimate"]
    if np.all(np.isfinite(opt_est)):
        text += (f"The validation estimate {'lies within' if ds.attrs['validated'] else 'lies OUTSIDE'} the "
                 f"optimisation estimate's limits {stat(opt_est)}.")
    else:
        text += (f"The optimisation estimate {stat(opt_est)} has no limits at {ds.attrs['design_realizations']} "
                 "drapes to check the validation estimate against.")
    if "margin" in ds.attrs:
        m = json.loads(ds.attrs["margin"])["validation"]
        beats = m[1] > 0
        text += (f" Uniform minus sector {name} at the same total {sum(opt[:n_forces]):.0f} N: {stat(m)}: the sector "
                 f"design {'beats' if beats else 'does NOT beat'} the uniform force by more than its limits.")
    limit = ds.attrs["max_draw_in_mm"]
    if limit != "none":
        d = val["optimum"]["draw_in"]
        kept = (d[2] if ds.attrs["statistic"] == "upper" else d[0]) <= limit
        none_kept = not ds["feasible"].values[ds["sample"].values == "design"].any()
        text += (f" Draw-in at the optimum (95 % quantile of the largest, mm): {stat(d)}, limit {limit:g} mm on its "
                 f"{ds.attrs['statistic']}: {'kept' if kept else 'BROKEN'} on the validation sample"
                 + ("; no evaluated design keeps it." if none_kept else "."))
    if ds.attrs.get("rare", "none") != "none":
        rare = json.loads(ds.attrs["rare"])
        p = val["optimum"]["rare"]
        kept = (p[2] if ds.attrs["statistic"] == "upper" else p[0]) <= rare["max_probability"]
        design = ds["sample"].values == "design"
        text += (f" P({rare['qoi']} >= {rare['threshold']:g}) at the optimum: {stat(p)} (an independent estimate on "
                 f"the validation seed; {np.median(ds['rare_drapes'].values):,.0f} drapes a design, median), bound "
                 f"{rare['max_probability']:g} on its {ds.attrs['statistic']}: {'kept' if kept else 'BROKEN'}"
                 + ("; no evaluated design keeps the limits." if not ds["feasible"].values[design].any() else "."))
    return text
