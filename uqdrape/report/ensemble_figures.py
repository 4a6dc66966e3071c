"""Figures of an ensemble: node maps, line statistics, histograms, convergence, force sweeps.

Each function takes the ensemble Dataset (dims blankholder_force, realization, i, j; a
drape Dataset is put in that layout first, see ``figures``), computes what it needs with ``uqdrape.stats`` unless the
statistics are passed in (``write_report`` computes them once), draws one panel per
blank-holder level where that applies, writes a PNG and returns its path. Maps are
drawn on the ensemble-mean node positions (x, y in mm).
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Sequence
from pathlib import Path

import matplotlib as mpl
import numpy as np
import xarray as xr
from matplotlib.tri import Triangulation
from scipy import stats

from uqdrape.drape.lines import max_shear_lines
from uqdrape.drape.net import net_quads
from uqdrape.schema import FORCE, QUADRANTS, REALIZATION, SOLVER_INPUTS
from uqdrape.stats import (convergence, exceedance_probability, line_scalars, line_statistics, mean_statistics,
                           node_histogram, node_statistics, samples_needed, wrinkle_risk)
from uqdrape.stats.headline import argmax_site

from ..experimental import as_experimental
from .figures import (DISTANCE_LABEL, MINUS_COLOR, PLUS_COLOR, QUADRANT_STYLE, SHEAR_LABEL, describe, force_groups,
                      force_title, label, overlay_experimental, panels, report_figure, save, shared_ylim, suptitle)
from .style import NOTE_PT

#: Probability level of the shaded band of the realisations along the max-shear lines.
BAND = 0.95
#: (variable of ``uqdrape.stats.line_scalars``, colour, legend text) of the line-mean plots.
_LINE_SCALARS = (("plus_mean_shear", PLUS_COLOR, "+ quadrants (i·j > 0)"),
                 ("minus_mean_shear", MINUS_COLOR, "− quadrants (i·j < 0)"),
                 ("asymmetry", "black", "asymmetry (plus + minus)"))


def blank_view(ds: xr.Dataset) -> bool:
    """Whether the maps of ``ds`` are drawn on the flat blank: a mesh mould may have walls,
    whose nodes share plan positions, so its maps put node (i, j) at (i s, j s) instead."""
    return json.loads(ds.attrs.get("geometry_json", "{}")).get("kind") == "mesh"


def map_labels(ds: xr.Dataset) -> tuple[str, str]:
    """Axis labels of the maps of ``ds`` (see ``blank_view``)."""
    return ("i · s, flat blank (mm)", "j · s, flat blank (mm)") if blank_view(ds) else ("x (mm)", "y (mm)")


def mean_positions(ds: xr.Dataset) -> xr.Dataset:
    """Map positions (mm) of the nodes per level: the ensemble-mean x, y over the valid
    realisations, or on a mesh mould (``blank_view``) the flat blank's (i s, j s) where the
    mean is valid."""
    pos = ds[["x", "y"]].mean(REALIZATION).compute()
    if blank_view(ds):
        s = float(ds.attrs["spacing_mm"])
        valid = np.isfinite(pos["x"])
        pos["x"] = (ds["i"] * s).broadcast_like(pos["x"]).where(valid)
        pos["y"] = (ds["j"] * s).broadcast_like(pos["y"]).where(valid)
    return pos


def triangulation(x: np.ndarray, y: np.ndarray, valid: np.ndarray):
    """Triangles (two per net cell with four valid nodes) on the valid nodes; (Triangulation, flat index)."""
    used, quads = net_quads(valid)
    tris = np.concatenate([quads[:, :3], quads[:, [0, 2, 3]]])
    if tris.size == 0:
        raise ValueError("no net cell has four valid nodes; nothing to map")
    return Triangulation(x.flat[used], y.flat[used], tris), used


def _map(ds: xr.Dataset, values: xr.DataArray, path, *, norm, cmap, cbar_label: str, title: str,
         mark=None) -> Path:
    """Draw ``values`` (dims blankholder_force, i, j) on the mean node positions, one panel per level.

    ``mark(force) -> (i, j, text) | str | None`` annotates one node per panel, or writes a
    note across it (a panel with nothing to point at says so rather than stay blank).
    """
    pos = mean_positions(ds)
    groups = force_groups(pos)
    fig, axes = panels(len(groups), size=(5.4, 4.8))
    for ax, (force, xy) in zip(axes, groups):
        v = values.sel({FORCE: force}).transpose("i", "j").values
        x, y = xy["x"].transpose("i", "j").values, xy["y"].transpose("i", "j").values
        tri, used = triangulation(x, y, np.isfinite(x) & np.isfinite(y) & np.isfinite(v))
        ax.set_facecolor("0.9")  # the net stands out where its values are white (no risk)
        ax.tripcolor(tri, v.flat[used], shading="gouraud", norm=norm, cmap=cmap, rasterized=True)
        xlabel, ylabel = map_labels(ds)
        ax.set(xlabel=xlabel, ylabel=ylabel, aspect="equal", title=force_title(force))
        m = None if mark is None else mark(force)
        if isinstance(m, str):
            ax.text(0.5, 0.5, m, transform=ax.transAxes, ha="center", va="center", fontsize=NOTE_PT,
                    bbox=dict(boxstyle="round", fc="white", alpha=0.9))
        elif m is not None:
            i, j, text = m
            px, py = float(xy["x"].sel(i=i, j=j)), float(xy["y"].sel(i=i, j=j))
            ax.plot(px, py, marker="o", markersize=9, markerfacecolor="none", markeredgecolor="black", mew=1.5)
            # the label points into the net, so it stays inside the panel and off its title
            right, top = px > np.nanmean(x), py > np.nanmean(y)
            ax.annotate(text, (px, py), xytext=(-8 if right else 8, -8 if top else 8), textcoords="offset points",
                        ha="right" if right else "left", va="top" if top else "bottom", fontsize=NOTE_PT,
                        bbox=dict(boxstyle="round", fc="white", alpha=0.8))
    fig.colorbar(mpl.cm.ScalarMappable(norm=norm, cmap=cmap), ax=axes, shrink=0.85, label=cbar_label)
    suptitle(fig, title, describe(ds))
    return save(fig, path)


def _node_mark(da: xr.DataArray, fmt, zero: str | None = None):
    """A ``mark`` callback: ``fmt(site)`` at the largest entry of ``da`` in each level; where
    that entry is 0 (e.g. no risk at this level) the note ``zero``, or nothing.

    ``site`` is {dim: value} of that entry, the level included.
    """
    def mark(force):
        sub = da.sel({FORCE: force})
        site = argmax_site(sub)
        if site is None or float(sub.sel(site)) == 0.0:
            return zero
        return site["i"], site["j"], fmt({**site, FORCE: force})
    return mark


#: Probability maps: white at 0 (no risk reads as blank paper, not as a pale colour), then reds.
RISK_CMAP = mpl.colors.ListedColormap(
    np.vstack([[1.0, 1.0, 1.0, 1.0], mpl.colormaps["Reds"](np.linspace(0.08, 1.0, 255))]), name="risk")


@report_figure
def plot_mean_map(ds: xr.Dataset, path, *, node_stats: xr.Dataset | None = None) -> Path:
    """Map of the ensemble-mean node shear (deg; the shear itself for one drape per level),
    diverging colours centred on 0, one shared scale for all levels. Returns the path."""
    node_stats = node_statistics(ds) if node_stats is None else node_stats
    mean = node_stats["mean"]
    vmax = float(np.nanmax(np.abs(mean.values))) or 1.0
    n = ds.sizes[REALIZATION]
    what = "mean " if n > 1 else ""
    return _map(ds, mean, path, norm=mpl.colors.Normalize(-vmax, vmax), cmap=mpl.colormaps["RdBu_r"],
                cbar_label=f"{what}shear angle (deg)", title=f"{what}node shear" + (f", N = {n}" if n > 1 else ""),
                mark=_node_mark(abs(mean), lambda s: f"max |{what.strip() or 'shear'}| {float(abs(mean).sel(s)):.1f}°"))


@report_figure
def plot_sd_map(ds: xr.Dataset, path, *, node_stats: xr.Dataset | None = None) -> Path:
    """Map of the ensemble standard deviation of node shear (deg). Returns the path."""
    node_stats = node_statistics(ds) if node_stats is None else node_stats
    sd = node_stats["sd"]
    vmax = float(np.nanmax(sd.values)) if np.isfinite(sd.values).any() else 1.0
    return _map(ds, sd, path, norm=mpl.colors.Normalize(0.0, vmax or 1.0), cmap=mpl.colormaps["viridis"],
                cbar_label="standard deviation of shear (deg)",
                title=f"sd of node shear, N = {ds.sizes[REALIZATION]}",
                mark=_node_mark(sd, lambda s: f"max sd {float(sd.sel(s)):.2f}°"))


@report_figure
def plot_wrinkle_map(ds: xr.Dataset, path, *, threshold_deg: float | None = None,
                     exceedance: xr.Dataset | None = None) -> Path:
    """Map of the wrinkle risk per node: ``exceedance`` if given, else P(|shear| >
    ``threshold_deg``) if given, else ``uqdrape.stats.wrinkle_risk`` (locked-cell flag, or
    the locking angle). The node of highest probability is marked with the probability
    and its binomial confidence interval. Returns the path.
    """
    if exceedance is not None:
        ex = exceedance
    elif threshold_deg is not None:
        ex = exceedance_probability(ds, threshold_deg)
        ex.attrs["risk"] = f"P(|shear| > {float(threshold_deg):g}°)"
    else:
        ex = wrinkle_risk(ds)
        if ex is None:
            raise ValueError("no wrinkle risk: the ensemble has no 'locked' flag and no 'locking_angle_deg' "
                             "attribute; pass threshold_deg")
    p = ex["probability"]
    risk = ex.attrs.get("risk", f"P(|shear| > {float(ex['threshold']):g}°)")

    def text(site):
        s = ex.sel(site)
        return (f"max P = {float(s['probability']):.2f} "
                f"[{float(s['probability_lower']):.2f}, {float(s['probability_upper']):.2f}]")

    return _map(ds, p, path, norm=mpl.colors.Normalize(0.0, 1.0), cmap=RISK_CMAP,
                cbar_label=f"{risk} (-)",
                title=f"wrinkle risk {risk}, N = {ds.sizes[REALIZATION]}",
                mark=_node_mark(p, text, zero=f"no node at risk:\n{risk} = 0\nat every node "
                                               f"in {ds.sizes[REALIZATION]} drapes"))


@report_figure
def plot_line_statistics(ds: xr.Dataset, path, *, line_stats: xr.Dataset | None = None, experimental=None) -> Path:
    """Ensemble shear against mean distance from the crossover along the max-shear lines (thesis Figs 5.18/5.19).

    Per quadrant (i*j > 0 red, others blue): the mean with ±1 sd bars in shear and
    distance, and a shaded band holding the central 95 % of the realisations (empirical
    2.5 %/97.5 % quantiles per node). One panel per blank-holder level; ``experimental``
    (CSV path) overlays measured points. Returns the path.
    """
    points = as_experimental(experimental)
    st = line_statistics(ds, "max") if line_stats is None else line_stats
    tail = (1.0 - BAND) / 2.0
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "All-NaN slice", RuntimeWarning)  # lines end at invalid nodes: NaN band
        band = max_shear_lines(ds)["shear"].quantile([tail, 1.0 - tail], dim=REALIZATION, skipna=True).compute()
    groups = force_groups(st)
    fig, axes = panels(len(groups), size=(5.8, 4.6))
    for ax, (force, s) in zip(axes, groups):
        b = band.sel({FORCE: force})
        for q in QUADRANTS:
            style = QUADRANT_STYLE[q]
            sq = s.sel(quadrant=q)
            d = sq["distance_mean"].values
            ax.fill_between(d, b.sel(quadrant=q, quantile=tail).values, b.sel(quadrant=q, quantile=1 - tail).values,
                            color=style["color"], alpha=0.12, linewidth=0)
            ax.errorbar(d, sq["shear_mean"].values, yerr=sq["shear_sd"].values, xerr=sq["distance_sd"].values,
                        color=style["color"], marker=style["marker"], markersize=4, linestyle=style["linestyle"],
                        linewidth=1.2, elinewidth=0.8, capsize=2,
                        label=f"{q} ({'+' if q in ('++', '--') else '−'} quadrant) mean ± 1 sd")
        ax.fill_between([], [], [], color="0.5", alpha=0.25, label=f"central {BAND:.0%} of realisations")
        overlay_experimental(ax, points, force)
        ax.axhline(0.0, color="0.6", linewidth=0.8)
        ax.set(xlabel="mean " + DISTANCE_LABEL, ylabel=SHEAR_LABEL, title=force_title(force))
        ax.grid(alpha=0.3)
        ax.legend(loc="best")
    shared_ylim(axes)
    suptitle(fig, f"max-shear lines, N = {ds.sizes[REALIZATION]}", describe(ds))
    return save(fig, path)


def _node_kind(node) -> str:
    i, j = node
    return "+ quadrant" if i * j > 0 else "− quadrant" if i * j < 0 else "on an arm"


@report_figure
def plot_histograms(ds: xr.Dataset, path, nodes: Sequence[Sequence[int]], *, bins: int = 20) -> Path:
    """Histograms of node shear at ``nodes`` [(i, j), ...] with the fitted Normal (thesis Fig 5.20).

    One row per node and one column per blank-holder level (one row of nodes for one
    level); each panel has its own bins over its own range, titled with node and force,
    because the levels' distributions lie far apart compared with their widths. Returns
    the path.
    """
    nodes = [tuple(int(v) for v in node) for node in nodes]
    if not nodes:
        raise ValueError("nodes must list at least one (i, j) node")
    groups = force_groups(ds)
    fig, grid = panels(len(nodes) * len(groups), size=(4.6, 3.6), cols=len(groups) if len(groups) > 1 else None)
    for ax, (node, (force, level)) in zip(grid, ((n, g) for n in nodes for g in groups)):
        h = node_histogram(level, node, bins=bins)
        edges = h["bin_edges"].values
        mu, sd, n = float(h["normal_mean"]), float(h["normal_sd"]), int(h["n_valid"])
        ax.stairs(h["density"].values, edges, fill=True, color="tab:gray", alpha=0.6, label=f"histogram, n = {n}")
        if sd > 0:
            fine = np.linspace(edges[0], edges[-1], 200)
            ax.plot(fine, stats.norm.pdf(fine, mu, sd), color="black", linewidth=1.5,
                    label=f"Normal μ = {mu:.1f}°, σ = {sd:.2f}°")
        ax.set(xlabel=SHEAR_LABEL, ylabel="density (1/deg)",
               title=f"node {node}, {_node_kind(node)}, {force_title(force)}")
        ax.grid(alpha=0.3)
        ax.set_ylim(0.0, 1.35 * ax.get_ylim()[1])  # headroom: the legend sits above the bars
        ax.legend(loc="upper left")
    fig.suptitle(f"node shear distributions, N = {ds.sizes[REALIZATION]}" + (" per level" if len(groups) > 1 else ""))
    return save(fig, path)


def most_variable_node(ds: xr.Dataset, node_stats: xr.Dataset | None = None) -> tuple[int, int]:
    """(i, j) of the node with the largest shear sd (over all blank-holder levels)."""
    node_stats = node_statistics(ds) if node_stats is None else node_stats
    site = argmax_site(node_stats["sd"])
    if site is None:
        raise ValueError("no node has a finite shear sd (fewer than 2 valid realisations everywhere)")
    return int(site["i"]), int(site["j"])


@report_figure
def plot_convergence(ds: xr.Dataset, path, node: Sequence[int] | None = None, *, target_deg: float = 1.0,
                     confidence: float = 0.95, node_stats: xr.Dataset | None = None) -> Path:
    """Running mean (with its confidence band) and interval half-width of node shear against N.

    ``node`` defaults to the most variable node. The half-width panel (log-log) marks
    ``target_deg`` and the N needed to reach it at the final sd (``samples_needed``, t).
    One line per blank-holder level. Returns the path.
    """
    if not (np.isfinite(target_deg) and target_deg > 0):
        raise ValueError(f"target_deg must be > 0 (deg), got {target_deg!r}")
    node = most_variable_node(ds, node_stats) if node is None else tuple(int(v) for v in node)
    conv = convergence(ds, node, confidence=confidence)
    fig, (ax_m, ax_h) = panels(2, size=(5.8, 4.4))
    groups = force_groups(conv)
    cmap = mpl.colormaps["viridis"]
    for k, (force, c) in enumerate(groups):
        color = cmap(k / max(len(groups) - 1, 1))
        n = c["n"].values
        m, h = c["running_mean"].values, c["half_width"].values
        ax_m.plot(n, m, color=color, label=f"running mean, {force:g} N")
        ax_m.fill_between(n, m - h, m + h, color=color, alpha=0.2, linewidth=0)
        ax_h.loglog(n, h, color=color, label=f"half-width, {force:g} N")
        sd = float(c["running_sd"].values[-1])
        if np.isfinite(sd) and sd > 0:
            need = samples_needed(sd, target_deg, confidence)
            ax_h.axvline(need, color=color, linestyle=":", linewidth=1.2,
                         label=f"{force:g} N: N = {need} for ±{target_deg:g}°")
    ax_h.axhline(target_deg, color="0.3", linestyle="--", linewidth=1.0, label=f"target ±{target_deg:g}°")
    ax_m.set(xlabel="number of realisations N (-)", ylabel="running mean shear (deg)",
             title=f"running mean, {confidence:.0%} band")
    ax_h.set(xlabel="number of realisations N (-)", ylabel=f"{confidence:.0%} half-width of the mean (deg)",
             title="interval half-width")
    for axis in (ax_h.xaxis, ax_h.yaxis):
        axis.set_major_formatter(mpl.ticker.ScalarFormatter())
        axis.set_minor_formatter(mpl.ticker.NullFormatter())
    for ax in (ax_m, ax_h):
        ax.grid(alpha=0.3, which="both")
        ax.legend(loc="best")
    fig.suptitle(f"convergence of the mean shear at node {node} ({_node_kind(node)})")
    return save(fig, path)


@report_figure
def plot_sweep(ds: xr.Dataset, path, *, scalars: xr.Dataset | None = None) -> Path:
    """Max-shear line means ± 1 sd against blank-holder force (N) for a sweep ensemble.

    Left: mean signed shear along the + quadrant (i*j > 0) and − quadrant lines; right:
    their asymmetry (plus + minus, 0 when mirrored), from ``uqdrape.stats.line_scalars``.
    Needs two or more blank-holder levels. Returns the path.
    """
    if ds.sizes[FORCE] < 2:
        raise ValueError(f"plot_sweep needs two or more {FORCE!r} levels (a force sweep); dims: {dict(ds.sizes)}")
    sc = line_scalars(ds) if scalars is None else scalars
    force = ds[FORCE].values.astype(float)
    n = ds.sizes[REALIZATION]
    fig, (ax_q, ax_a) = panels(2, size=(5.8, 4.4))
    for var, color, text in _LINE_SCALARS:
        st = mean_statistics(sc[var]).transpose(FORCE)
        ax = ax_a if var == "asymmetry" else ax_q
        ax.errorbar(force, st["mean"].values, yerr=st["sd"].values, color=color, marker="o", capsize=3,
                    label=f"{text}, mean ± 1 sd" if n > 1 else text)
    for ax in (ax_q, ax_a):
        ax.axhline(0.0, color="0.6", linewidth=0.8)
        ax.set_xlabel("blank-holder force F_BH (N)")
        ax.grid(alpha=0.3)
        ax.legend(loc="best")
    k_max = sc.attrs.get("k_max")
    ax_q.set(ylabel="line-mean shear (deg)", title=f"mean shear over line nodes k = 1..{k_max}")
    ax_a.set(ylabel="asymmetry (deg)", title="± quadrant asymmetry")
    suptitle(fig, f"blank-holder force sweep, {f'N = {n}' if n > 1 else 'one drape'} per level", describe(ds))
    return save(fig, path)


#: Thesis quadrant numbers (Fig 5.6: Q1-Q4) of the max-shear quadrant labels, counter-clockwise from (+i, +j).
QUADRANT_NUMBER = {"++": 1, "-+": 2, "--": 3, "+-": 4}


@report_figure
def plot_scalar_vs_factor(ds: xr.Dataset, path, factor: str) -> Path:
    """Per-realisation scalars against one sampled scalar factor (thesis Fig 5.6 style).

    Left: blank-holder friction energy (J) per quadrant Q1-Q4 (Q1 = ++, counter-clockwise)
    and in total; right: line-mean shear of the + and − quadrant max-shear lines and their
    asymmetry (deg, ``uqdrape.stats.line_scalars``). ``factor`` is a solver input
    (``uqdrape.schema.SOLVER_INPUTS``, e.g. ``skew``, deg). Not for a blank-holder sweep
    (use ``plot_sweep``). Returns the path.
    """
    if ds.sizes[FORCE] > 1:
        raise ValueError(f"plot_scalar_vs_factor takes one blank-holder level; ds has {ds.sizes[FORCE]} "
                         "(select a level first, or use plot_sweep)")
    ds = ds.isel({FORCE: 0})
    stored = [name for name, inp in SOLVER_INPUTS.items() if inp.variable in ds.data_vars]
    if factor not in stored:
        raise ValueError(f"factor={factor!r} is not a variable along {REALIZATION!r}; valid: {', '.join(stored)}")
    x = ds[SOLVER_INPUTS[factor].variable].values.astype(float)
    order = np.argsort(x)
    xlabel = label(ds[SOLVER_INPUTS[factor].variable])
    fig, (ax_e, ax_s) = panels(2, size=(5.8, 4.4))
    if "energy_blankholder_quadrant" in ds.data_vars:
        eq = ds["energy_blankholder_quadrant"].transpose(REALIZATION, "quadrant").values
        for k, q in enumerate(ds["quadrant"].values):
            # mirrored quadrants often coincide: their own marker and dash keep both visible
            ax_e.plot(x[order], eq[order, k], color=QUADRANT_STYLE[q]["color"], marker=QUADRANT_STYLE[q]["marker"],
                      markersize=3.5, linestyle=QUADRANT_STYLE[q]["linestyle"], linewidth=1.0,
                      fillstyle="none" if QUADRANT_STYLE[q]["linestyle"] == "--" else "full",
                      label=f"Q{QUADRANT_NUMBER[q]} ({q}, {'+' if q in ('++', '--') else '−'} quadrant)")
    ax_e.plot(x[order], ds["energy_blankholder"].values[order], marker="o", markersize=4, color="black",
              linewidth=1.5, label="total")
    ax_e.set(xlabel=xlabel, ylabel="blank-holder energy (J)", title="blank-holder friction energy")
    sc = line_scalars(ds)
    for var, color, text in _LINE_SCALARS:
        ax_s.plot(x[order], sc[var].values[order], marker=".", color=color, label=text)
    ax_s.axhline(0.0, color="0.6", linewidth=0.8)
    ax_s.set(xlabel=xlabel, ylabel="line-mean shear (deg)",
             title=f"max-shear lines, mean over nodes k = 1..{sc.attrs.get('k_max')}")
    for ax in (ax_e, ax_s):
        ax.grid(alpha=0.3)
        ax.legend(loc="best")
    suptitle(fig, f"each drape against {factor}, N = {ds.sizes[REALIZATION]}", describe(ds))
    return save(fig, path)
