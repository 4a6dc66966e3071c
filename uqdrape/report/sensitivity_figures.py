"""Figures of a sensitivity analysis (``uqdrape.sensitivity``): index bars with their
confidence intervals per quantity of interest, indices against blank-holder force per
factor, and index maps of node shear on the net.

Inputs are the Datasets ``uqdrape.workflow.write_sensitivity`` stores: QoI indices (dims factor, qoi,
blankholder_force) and node-shear index maps (dims factor, i, j, blankholder_force),
Sobol' (S1, ST and their ``_conf`` half-widths) or Morris (mu_star, mu_star_conf).
Error bars and bands are the stored bootstrap confidence half-widths.
"""

from __future__ import annotations

import matplotlib as mpl
import numpy as np
import xarray as xr
from matplotlib.lines import Line2D

from .ensemble_figures import blank_view, mean_positions, triangulation
from ..schema import FORCE
from .figures import describe, force_groups, force_title, panels, report_figure, save, suptitle, unit_text

#: The indices drawn per method: (variable, its confidence half-width, label).
INDICES = {
    "sobol": (("S1", "S1_conf", "first-order S1"), ("ST", "ST_conf", "total-order ST")),
    "morris": (("mu_star", "mu_star_conf", "Morris μ*"),),
}


def _method(ds: xr.Dataset) -> str:
    method = ds.attrs.get("method")
    if method not in INDICES:
        raise ValueError(f"the indices Dataset has method={method!r} in its attributes; expected one of {tuple(INDICES)}")
    return method


def _sample_text(ds: xr.Dataset) -> str:
    what = "base samples" if ds.attrs["method"] == "sobol" else "trajectories"
    return (f"{ds.attrs['method']}: {ds.attrs['base_samples']} {what}, {ds.attrs['n_evaluations']} drapes per level, "
            f"{100 * ds.attrs['conf_level']:g} % bootstrap intervals")


def _qoi_axis_label(ds: xr.Dataset, q: str) -> str:
    if ds.attrs["method"] == "sobol":
        return "index (-)"
    units = unit_text(str(ds["qoi_units"].sel(qoi=q).values))
    return f"μ* ({'' if units == '-' else units + ' '}per unit step)"


@report_figure
def plot_sensitivity_bars(indices: xr.Dataset, path):
    """Bar chart per quantity of interest (rows) and blank-holder level (columns; one level:
    the QoIs fill a grid): each factor's indices (Sobol' S1 and ST side by side, or Morris
    μ*) with their confidence intervals as error bars. Returns the path."""
    method = _method(indices)
    pairs = INDICES[method]
    groups = force_groups(indices)
    qois = [str(q) for q in indices["qoi"].values]
    factors = [str(f) for f in indices["factor"].values]
    size = (max(3.6, 0.9 * len(factors) + 1.2), 3.6)
    # one level: the QoIs fill a grid of up to 3 columns; else a row per QoI, a column per level
    cols = min(3, len(qois)) if len(groups) == 1 else len(groups)
    fig, axes = panels(len(qois) * len(groups), size=size, cols=cols)
    axes = np.reshape(axes, (len(qois), len(groups)))
    x = np.arange(len(factors))
    width = 0.8 / len(pairs)
    colors = ("tab:blue", "tab:orange")
    for row, q in enumerate(qois):
        for col, (force, level) in enumerate(groups):
            ax = axes[row, col]
            sel = level.sel(qoi=q)
            for k, (var, conf, name) in enumerate(pairs):
                ax.bar(x + (k - (len(pairs) - 1) / 2) * width, sel[var].values, width, yerr=sel[conf].values,
                       color=colors[k], capsize=3, label=name, error_kw={"elinewidth": 1.0})
            if bool(sel["output_constant"]):
                ax.text(0.5, 0.5, "constant over the sample", transform=ax.transAxes, ha="center", color="0.4")
            ax.axhline(0.0, color="0.5", linewidth=0.8)
            ax.set_xticks(x, factors, rotation=30, ha="right")
            ax.grid(axis="y", alpha=0.3)
            if method == "sobol":
                ax.set_ylim(min(-0.1, ax.get_ylim()[0]), max(1.1, ax.get_ylim()[1]))
            ax.set(title=f"{q}, {force_title(force)}", ylabel=_qoi_axis_label(indices, q))
    axes[0, 0].legend(loc="upper left")
    fig.suptitle(f"sensitivity indices per quantity of interest\n{_sample_text(indices)}")
    return save(fig, path)


@report_figure
def plot_sensitivity_vs_force(indices: xr.Dataset, path):
    """Indices against blank-holder force (N), one panel per quantity of interest and one
    colour per factor: ST solid and S1 dashed (Morris: μ*), shaded confidence intervals.
    Returns the path."""
    method = _method(indices)
    pairs = INDICES[method]
    qois = [str(q) for q in indices["qoi"].values]
    force = indices[FORCE].values.astype(float)
    fig, axes = panels(len(qois), size=(5.0, 3.9), cols=min(3, len(qois)))
    cmap = mpl.colormaps["tab10"]
    styles = {"ST": "-", "S1": "--", "mu_star": "-"}
    for n, q in enumerate(qois):
        ax = axes[n]
        for k, factor in enumerate(indices["factor"].values):
            sel = indices.sel(qoi=q, factor=factor).transpose(FORCE)
            for var, conf, name in pairs:
                v, c = sel[var].values, sel[conf].values
                ax.plot(force, v, color=cmap(k % 10), linestyle=styles[var], marker="o", markersize=4)
                ax.fill_between(force, v - c, v + c, color=cmap(k % 10), alpha=0.12, linewidth=0)
        ax.axhline(0.0, color="0.5", linewidth=0.8)
        ax.set(xlabel="blank-holder force F_BH (N)", ylabel=_qoi_axis_label(indices, q), title=q)
        ax.grid(alpha=0.3)
    # one legend entry per factor (its colour) and per index (its line style, drawn long enough to read)
    handles = [Line2D([], [], color=cmap(k % 10), linewidth=6, label=str(f))
               for k, f in enumerate(indices["factor"].values)]
    handles += [Line2D([], [], color="0.2", linestyle=styles[var], label=name) for var, _, name in pairs]
    fig.legend(handles=handles, loc="outside right upper", handlelength=3.5)
    fig.suptitle(f"sensitivity against blank-holder force, bands: confidence intervals\n{_sample_text(indices)}")
    return save(fig, path)


@report_figure
def plot_sensitivity_map(ds: xr.Dataset, maps: xr.Dataset, path, index: str = "ST"):
    """Index ``index`` (S1, ST or mu_star) of node shear on the net: one row per factor,
    one column per blank-holder level, drawn on the ensemble-mean node positions of the
    ensemble ``ds``. Nodes invalid in some evaluation are left blank. Returns the path."""
    method = _method(maps)
    valid = [var for var, _, _ in INDICES[method]]
    if index not in valid:
        raise ValueError(f"index={index!r} is not a {method} index; valid: {', '.join(valid)}")
    pos = mean_positions(ds)
    groups = force_groups(maps)
    factors = [str(f) for f in maps["factor"].values]
    fig, axes = panels(len(factors) * len(groups), size=(2.9, 2.7), cols=len(groups))
    axes = np.reshape(axes, (len(factors), len(groups)))
    values = maps[index].values
    top = float(np.nanmax(values)) if np.isfinite(values).any() else 1.0
    norm = mpl.colors.Normalize(0.0, 1.0 if method == "sobol" else (top or 1.0))
    cmap = mpl.colormaps["magma_r"]
    for col, (force, level) in enumerate(groups):
        xy = pos.sel({FORCE: force})
        x, y = xy["x"].transpose("i", "j").values, xy["y"].transpose("i", "j").values
        for row, factor in enumerate(factors):
            ax = axes[row, col]
            v = level[index].sel(factor=factor).transpose("i", "j").values
            ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(v)
            if ok.sum() >= 3:
                tri, used = triangulation(x, y, ok)
                ax.tripcolor(tri, v.flat[used], shading="gouraud", norm=norm, cmap=cmap, rasterized=True)
            ax.set(aspect="equal", xticks=[], yticks=[])
            ax.set_title(f"{factor}, {force_title(force)}")
    label = f"{index} of node shear" + (" (-)" if method == "sobol" else " (deg per unit step)")
    fig.colorbar(mpl.cm.ScalarMappable(norm=norm, cmap=cmap), ax=axes, shrink=0.8, label=label)
    where = "the flat blank" if blank_view(ds) else "the mean net (x-y plan)"
    suptitle(fig, f"{index} of node shear on {where}, {describe(ds)}", _sample_text(maps))
    return save(fig, path)
