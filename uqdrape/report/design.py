"""The report page of a blank-holder design (``uqdrape.design``): figures, index.html, summary.json.

Figures: the objective against the total force with its confidence band, the optimiser's
convergence, the sector forces at the optimum as polar bars on the part outline (sector
designs), and the risk map P(node locked) of the baseline and the optimum on the
validation sample. Input is the ``design.nc`` Dataset and the mould.
"""

from __future__ import annotations

import html
import json
import textwrap
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr
from ..files import write_text_atomic
from ..schema import DRAW_IN
from .ensemble_figures import RISK_CMAP
from .figures import panels, save
from .style import NOTE_PT, canvas, check_formats, styled, vector_formats
from .page import figures_html, page, provenance, provenance_line

_LABELS = {"p_locked": "P(any node locked)", "q95_max_abs_shear": "95 % quantile of max |shear| (deg)",
           "abs_mean_asymmetry": "|mean asymmetry| (deg)", "q95_max_draw_in": "95 % quantile of max draw-in (mm)"}


def _design(ds: xr.Dataset) -> xr.Dataset:
    return ds.isel(evaluation=np.flatnonzero(ds["sample"].values == "design"))


def _validation(ds: xr.Dataset) -> dict:
    return json.loads(ds.attrs["validation"])


def _n_forces(ds: xr.Dataset) -> int:
    return sum(v != "friction" for v in np.atleast_1d(ds.attrs["variables"]))


def _statistic_panel(ax, ds: xr.Dataset, name: str, validation_key: str):
    """Statistic ``name`` of every design (estimate, confidence limits) against the total
    force (N), designs that break the draw-in limit crossed; the baseline, uniform and
    optimum designs on the validation sample (their ``validation_key`` triple) marked."""
    c = ds.attrs["confidence"]
    d = _design(ds)
    order = np.argsort(d["total_force"].values, kind="stable")
    F = d["total_force"].values[order]
    est, lo, hi = (d[name + s].values[order] for s in ("", "_lower", "_upper"))
    uniform = _n_forces(ds) == 1 and "friction" not in np.atleast_1d(ds.attrs["variables"])
    if uniform:
        ax.fill_between(F, lo, hi, color="tab:blue", alpha=0.25, lw=0, label=f"{c:.0%} confidence band")
        ax.plot(F, est, "o-", color="tab:blue", ms=3.5, label="estimate (common random numbers)")
    else:
        ax.errorbar(F, est, yerr=[est - lo, hi - est], fmt="o", color="tab:blue", ms=3.5, alpha=0.7,
                    elinewidth=0.8, label=f"each design: estimate, {c:.0%} limits")
    broken = d["feasible"].values[order] == 0
    if broken.any():
        limits = [what for what, key in (("the draw-in limit", "max_draw_in_mm"), ("the rare constraint", "rare"))
                  if ds.attrs.get(key, "none") != "none"]
        ax.plot(F[broken], est[broken], "x", color="0.3", ms=7, mew=1.5, label=f"breaks {' or '.join(limits)}")
    n = _n_forces(ds)
    for role, colour, marker, size in (("baseline", "tab:red", "s", 6), ("uniform", "tab:orange", "o", 6),
                                       ("optimum", "tab:green", "D", 10)):
        v = _validation(ds).get(role)
        if v is None:
            continue
        e = v[validation_key]
        ax.errorbar([sum(v["x"][:n])], [e[0]], yerr=[[e[0] - e[1]], [e[2] - e[0]]], fmt=marker, color=colour,
                    ms=size, mfc="none" if role == "optimum" else colour, mew=2, capsize=3,
                    label=f"{role if role != 'uniform' else 'uniform at the optimum total'}, validation sample")
    _log_if_wide(ax, est)
    ax.set(xlabel="total blank-holder force (N)", ylabel=_LABELS[name])
    ax.grid(alpha=0.3)


@styled
def plot_objective(ds: xr.Dataset, path) -> Path:
    """The objective's statistic (estimate, confidence band) against the total force (N),
    design sample, the baseline and optimum on the validation sample marked; with a
    draw-in limit, a second panel of the draw-in statistic and the limit."""
    name = ds.attrs["objective"]
    limit = ds.attrs["max_draw_in_mm"]
    fig, axes = panels(1 if limit == "none" else 2, size=(7.0, 4.4 if limit == "none" else 3.8), cols=1)
    ax = axes[0]
    _statistic_panel(ax, ds, name, "estimate")
    if ds.attrs["target"] != "none":
        ax.axhline(float(ds.attrs["target"]), color="k", ls=":", lw=1, label=f"target {ds.attrs['target']:g}")
    ax.set_title(f"{ds.attrs['study_name']}: {_LABELS[name]} against force")
    ax.legend(loc="best")
    if limit != "none":
        ax2 = axes[1]
        ax2.sharex(ax)
        _statistic_panel(ax2, ds, DRAW_IN, "draw_in")
        ax2.axhline(float(limit), color="k", ls="--", lw=1,
                    label=f"draw-in limit {float(limit):g} mm (on the {ds.attrs['statistic']})")
        ax2.legend(loc="best")
    return save(fig, path)


def _log_if_wide(ax, values):
    """A log y axis when positive values span more than 1.5 decades."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size and v.min() > 0 and v.max() / v.min() > 30:
        ax.set_yscale("log")


@styled
def plot_design_history(ds: xr.Dataset, path) -> Path:
    """The objective of each design in the order evaluated, and the best so far."""
    d = _design(ds)
    f = d["objective"].values
    fig, (ax,) = panels(1, size=(7.0, 3.8))
    k = np.arange(1, f.size + 1)
    ax.plot(k, f, "o", color="tab:blue", ms=4, alpha=0.6, label="design evaluated")
    ax.plot(k, np.minimum.accumulate(f), "-", color="tab:green", lw=2, label="best so far")
    _log_if_wide(ax, f)
    ax.set(xlabel="evaluation (design sample)", ylabel="objective",
           title="\n".join(textwrap.wrap(f"{d['objective'].attrs['long_name']}; {ds.attrs['optimiser']}", 80)))
    ax.legend()
    ax.grid(alpha=0.3)
    return save(fig, path)


def _outline(ax, surface, extent: float):
    """The part's outline in plan: where the mould rises 1 % of its height above the flange."""
    x = np.linspace(-extent, extent, 241)
    X, Y = np.meshgrid(x, x)
    Z = np.where(surface.inside(X, Y), surface.height(X, Y), np.nan)
    level = np.nanmin(Z) + 0.01 * (np.nanmax(Z) - np.nanmin(Z))
    ax.contour(X, Y, Z, levels=[level], colors="0.3", linewidths=1.2)


@styled
def plot_sectors(ds: xr.Dataset, path, surface) -> Path:
    """Sector forces (N) at the optimum as polar bars on the part outline, with the
    uniform force at the same total as a dashed circle."""
    n = _n_forces(ds)
    opt = np.atleast_1d(ds.attrs["optimum"])[:n]
    lo, hi = (np.atleast_1d(ds.attrs[k])[:n] for k in ("optimum_lower", "optimum_upper"))
    xy = np.hypot(ds["optimum_node_x"], ds["optimum_node_y"])
    extent = 1.25 * float(xy.max())
    width = 2 * np.pi / n
    theta = (np.arange(n) + 0.5) * width
    top = float(np.max(hi))
    fig = canvas(6.4, 6.4)  # fixed axes: the polar bars share the plan's centre
    rect = [0.12, 0.08, 0.8, 0.8]
    ax = fig.add_axes(rect)
    _outline(ax, surface, extent)
    ax.set(aspect="equal", xlim=(-extent, extent), ylim=(-extent, extent), xlabel="x (mm)", ylabel="y (mm)")
    polar = fig.add_axes(rect, projection="polar", frameon=False)
    polar.bar(theta, opt, width=0.9 * width, color="tab:green", alpha=0.45, edgecolor="tab:green",
              label="sector force at the optimum")
    polar.errorbar(theta, opt, yerr=[opt - lo, hi - opt], fmt="none", ecolor="k", capsize=3, lw=1)
    polar.plot(np.linspace(0, 2 * np.pi, 181), np.full(181, opt.sum() / n), "--", color="tab:orange",
               label=f"uniform, same total ({opt.sum():.0f} N)")
    for t, f in zip(theta, opt):
        polar.text(t, f + 0.06 * top, f"{f:.0f} N", ha="center", va="center", fontsize=NOTE_PT)
    polar.set(ylim=(0, 1.2 * top), yticklabels=[], xticks=np.arange(n) * width, xticklabels=[])
    polar.grid(alpha=0.3)
    polar.legend(loc="lower left", bbox_to_anchor=(0.0, 0.0), framealpha=0.9)
    fig.suptitle(f"{ds.attrs['study_name']}: sector forces at the optimum on the part outline\n"
                 f"(bar radius: force, 0-{1.2 * top:.0f} N; error bars: the optimum's "
                 "resampling interval)", fontsize=NOTE_PT, x=0.12, ha="left")
    return save(fig, path)


@styled
def plot_risk_maps(ds: xr.Dataset, path) -> Path:
    """P(node locked) of the baseline and the optimum design (validation sample), in plan,
    on one colour scale from 0 to the larger of the two maps' maxima: a design's
    probabilities are small (a few drapes of 64), and on a 0-1 scale they would read as
    blank paper."""
    roles = ("baseline", "optimum")
    n = _n_forces(ds)
    val = _validation(ds)
    top = max(float(ds[f"{role}_node_p_locked"].max()) for role in roles) or 1.0
    fig, axes = panels(2, size=(5.5, 4.8))
    for ax, role in zip(axes, roles):
        p = ds[f"{role}_node_p_locked"].values.ravel()
        x, y = ds[f"{role}_node_x"].values.ravel(), ds[f"{role}_node_y"].values.ravel()
        ax.scatter(x[p == 0], y[p == 0], s=3, color="0.8", label="P = 0", rasterized=True)
        hot = p > 0
        im = ax.scatter(x[hot], y[hot], c=p[hot], s=10, cmap=RISK_CMAP, vmin=0, vmax=top, rasterized=True)
        if not hot.any():
            ax.legend(loc="upper right")
        ax.set(aspect="equal", title=f"{role}: total {sum(val[role]['x'][:n]):.0f} N, max P = {float(p.max()):.2f}",
               xlabel="x (mm)", ylabel="y (mm)")
    fig.colorbar(im, ax=axes, label=f"P(node next to a locked cell), validation sample (scale 0-{top:.2g})")
    return save(fig, path)


def _rare_limit(ds: xr.Dataset) -> str:
    """The ``[design] rare`` constraint in words ("none" without one)."""
    if ds.attrs.get("rare", "none") == "none":
        return "none"
    r = json.loads(ds.attrs["rare"])
    return (f"P({r['qoi']} >= {r['threshold']:g}) <= {r['max_probability']:g} on the {ds.attrs['statistic']}, "
            f"estimated per design to CoV {r['cov']:g} within {r['max_drapes']:,} drapes as a [study] rare is "
            "(importance sampling at the most probable point of subset levels, or subset simulation; method per design below)")


def _rare_table(ds: xr.Dataset) -> str:
    """Each evaluated design's rare estimate: force, P with its limits, CoV, drapes, method
    (with why, where its CoV is above the target or it is a bound), feasible."""
    if "rare_probability" not in ds:
        return ""
    notes = ds["rare_note"].values if "rare_note" in ds else [""] * ds.sizes["evaluation"]
    head = ("sample", "total force (N)", "P", "limits", "CoV", "drapes", "method", "feasible")
    rows = [(str(ds["sample"].values[e]), f"{ds['total_force'].values[e]:.1f}",
             ("< " if ds["rare_method"].values[e] == "below" else "") + f"{ds['rare_probability'].values[e]:.3g}",
             f"[{ds['rare_lower'].values[e]:.3g}, {ds['rare_upper'].values[e]:.3g}]",
             f"{ds['rare_cov'].values[e]:.3f}", f"{int(ds['rare_drapes'].values[e]):,}",
             str(ds["rare_method"].values[e]) + (f": {notes[e]}" if notes[e] else ""), "yes" if ds["feasible"].values[e] else "no")
            for e in np.argsort(ds["total_force"].values, kind="stable")]
    cells = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in rows)
    return ("<h2>Rare constraint per design</h2>\n<table><tr>" + "".join(f"<th>{h}</th>" for h in head)
            + f"</tr>{cells}</table>\n")


def _table(ds: xr.Dataset) -> str:
    rows = [("study", ds.attrs["study_name"]), ("objective", f"{ds.attrs['statistic']} of {ds.attrs['objective']}"
             + (f", target {ds.attrs['target']}" if ds.attrs["target"] != "none" else "")),
            ("variables and bounds", f"{', '.join(np.atleast_1d(ds.attrs['variables']))}: {ds.attrs['bounds']}"),
            ("total-force budget (N)", ds.attrs["budget_N"]),
            ("draw-in limit (mm)", ds.attrs["max_draw_in_mm"] if ds.attrs["max_draw_in_mm"] == "none" else
             f"{ds.attrs['max_draw_in_mm']:g} on the {ds.attrs['statistic']} of the 95 % quantile of the largest "
             "radial draw-in of the net's outermost ring"),
            ("rare constraint", _rare_limit(ds)),
            ("optimiser", ds.attrs["optimiser"]),
            ("designs evaluated", f"{int((ds['sample'] == 'design').sum())} x {ds.attrs['design_realizations']} "
                                  f"drapes (seed {ds.attrs['design_seed']})"),
            ("validation", f"{ds.attrs['validation_realizations']} fresh drapes (seed {ds.attrs['validation_seed']})"),
            ("line nodes of the asymmetry", f"1..{ds.attrs['k_max']}"),
            ("optimum interval", ds.attrs["optimum_interval"])]
    body = "".join(f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


def write_design_report(ds: xr.Dataset, out_dir, *, surface, formats: Sequence[str] = ()) -> Path:
    """Write the design report of ``ds`` (``design.nc``) into ``out_dir``: PNGs (and their
    copies in the vector ``formats``, svg or pdf), ``index.html`` and ``summary.json``;
    ``surface`` is the mould. Returns index.html."""
    formats = check_formats(formats)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with vector_formats(formats):
        return _write_design_report(ds, out, surface)


def _write_design_report(ds: xr.Dataset, out: Path, surface) -> Path:
    figures = [(plot_objective(ds, out / "objective.png"),
                "The objective's statistic of every design on the design sample (common random numbers) "
                "against the total force (the band is hidden under the line where the limits are within a few "
                "per cent), and the baseline and optimum re-draped on the validation sample"
                + ("; below, the draw-in statistic and its limit." if ds.attrs["max_draw_in_mm"] != "none" else "."))]
    if _n_forces(ds) > 1:
        figures.append((plot_sectors(ds, out / "sectors.png", surface),
                        "Sector forces at the optimum; sectors are equal angles from +x, anticlockwise."))
    figures.append((plot_risk_maps(ds, out / "risk_map.png"),
                    "Risk before (the study's own force) and after (the optimum), validation sample."))
    figures.append((plot_design_history(ds, out / "convergence.png"), "The optimiser's history."))
    summary = {k: v for k, v in ds.attrs.items() if k not in ("study_json", "wall_time_s")}
    summary["figures"] = [p.name for p, _ in figures]
    summary["provenance"] = prov = provenance(ds.attrs.get("wall_time_s"))
    for key in ("validation", "margin", "bounds", "rare"):
        if key in summary and summary[key] != "none":
            summary[key] = json.loads(summary[key])
    if "rare_probability" in ds:  # each design's rare estimate, as the page's table
        summary["rare_designs"] = {k: ds[k].values.tolist() for k in (
            "sample", "total_force", "rare_probability", "rare_lower", "rare_upper", "rare_cov", "rare_drapes",
            "rare_method", "feasible")}
    summary = json.loads(json.dumps(summary, default=lambda v: np.asarray(v).tolist()))
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=1))
    body = (f"<h1>{html.escape(ds.attrs['study_name'])}: blank-holder design</h1>\n"
            f"<p class=\"note\">{html.escape(provenance_line(prov))}</p>\n"
            f"<p><b>{html.escape(ds.attrs['summary'])}</b></p>\n{_table(ds)}\n{_rare_table(ds)}"
            f"<h2>Figures</h2>\n{figures_html(figures)}")
    return write_text_atomic(out / "index.html", page(f"{ds.attrs['study_name']}: blank-holder design", body))
