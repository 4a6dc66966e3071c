"""The report of a laminate: one page for the laminate, one report per ply.

``report/index.html`` holds what concerns the plies together: P(any ply locked) per force
level with its Wilson interval and each ply's P(locked), the map of P(a locked node of any
ply) on the tool (``uqdrape.stats.tool_lock_map``), and per ply the mean and the sd of
its fibre deviation from the nominal angle (``uqdrape.stats.fibre_deviation``). Each ply's
own report (``report/ply-<name>/``, the single-ply report of ``write_report``) holds its
node statistics, limits, wrinkle risk and histograms, linked from the ply table.
"""

from __future__ import annotations

import html
import json
from collections.abc import Sequence
from pathlib import Path

import matplotlib as mpl
import numpy as np
import xarray as xr

from ..files import write_text_atomic
from ..schema import FORCE, PLY, PLY_ANGLE, REALIZATION, ply_dataset
from ..stats import fibre_deviation, laminate_lock, tool_lock_map
from .ensemble_figures import RISK_CMAP, map_labels, mean_positions, triangulation
from .figures import force_title, panels, save, suptitle
from .html import LOAD_BYTES, write_report
from .page import figures_html, page, provenance, provenance_line
from .style import check_formats, styled, vector_formats


def ply_label(ds: xr.Dataset, ply) -> str:
    """"ply NAME (ANGLE deg)" of a laminate's ply."""
    return f"ply {ply} ({float(ds[PLY_ANGLE].sel({PLY: ply})):+g}°)"


@styled
def plot_tool_lock(ds: xr.Dataset, lock_map: xr.DataArray, path) -> Path:
    """P(a locked node of any ply) on the tool's plan raster, one panel per force level."""
    fig, axes = panels(ds.sizes[FORCE], size=(5.4, 4.8))
    norm = mpl.colors.Normalize(0.0, 1.0)
    for ax, force in zip(axes, ds[FORCE].values):
        m = lock_map.sel({FORCE: force})
        ax.set_facecolor("0.9")
        ax.pcolormesh(m["x"], m["y"], m.values, norm=norm, cmap=RISK_CMAP, shading="nearest", rasterized=True)
        ax.set(xlabel="x (mm)", ylabel="y (mm)", aspect="equal", title=force_title(force))
    fig.colorbar(mpl.cm.ScalarMappable(norm=norm, cmap=RISK_CMAP), ax=axes, shrink=0.85,
                 label="P(locked node of any ply)")
    suptitle(fig, f"laminate: P(any ply locked) on the tool, N = {ds.sizes[REALIZATION]}",
             f"{ds.sizes[PLY]} plies; grey: no ply reaches")
    return save(fig, path)


@styled
def plot_ply_maps(ds: xr.Dataset, values: xr.DataArray, path, *, norm, cmap, label: str, title: str) -> Path:
    """``values`` (dims ply, i, j) of the first force level on each ply's mean node
    positions, one panel per ply."""
    force = ds[FORCE].values[0]
    fig, axes = panels(ds.sizes[PLY], size=(4.6, 4.2))
    for ax, ply in zip(axes, ds[PLY].values):
        one = ply_dataset(ds.sel({FORCE: [force]}), ply)
        pos = mean_positions(one).isel({FORCE: 0})
        x, y = pos["x"].transpose("i", "j").values, pos["y"].transpose("i", "j").values
        v = values.sel({PLY: ply}).transpose("i", "j").values
        tri, used = triangulation(x, y, np.isfinite(x) & np.isfinite(y) & np.isfinite(v))
        ax.set_facecolor("0.9")
        ax.tripcolor(tri, v.flat[used], shading="gouraud", norm=norm, cmap=cmap, rasterized=True)
        xlabel, ylabel = map_labels(one)
        ax.set(xlabel=xlabel, ylabel=ylabel, aspect="equal", title=ply_label(ds, ply))
    (x0, x1), (y0, y1) = ((min(lim[0] for lim in lims), max(lim[1] for lim in lims))
                          for lims in ([ax.get_xlim() for ax in axes], [ax.get_ylim() for ax in axes]))
    for ax in axes:  # one plan window for every ply, so the plies compare at a glance on the same tool
        ax.set(xlim=(x0, x1), ylim=(y0, y1))
    fig.colorbar(mpl.cm.ScalarMappable(norm=norm, cmap=cmap), ax=axes, shrink=0.85, label=label)
    suptitle(fig, title, force_title(force) if ds.sizes[FORCE] > 1 else "")
    return save(fig, path)


def write_laminate_report(ds: xr.Dataset, out_dir, *, title: str, description: str | None = None,
                          study_text: str | None = None, wall_time_s: float | None = None,
                          formats: Sequence[str] = ()) -> Path:
    """Write a laminate ensemble's report (module docstring) into ``out_dir``: each ply's
    report in ``ply-<name>/``, the laminate's figures, ``summary.json`` and ``index.html``;
    returns the index.html path. Arguments as ``write_report``'s."""
    if PLY not in ds.dims:
        raise ValueError(f"write_laminate_report needs a laminate ensemble with a {PLY!r} dim; dims: {dict(ds.sizes)}")
    if ds.nbytes <= LOAD_BYTES:
        ds = ds.compute()
    formats = check_formats(formats)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plies = []
    for ply in ds[PLY].values:
        one = ply_dataset(ds, ply)
        index = write_report(one, out / f"ply-{ply}", title=f"{title}: {ply_label(ds, ply)}",
                             description=description, wall_time_s=wall_time_s, formats=formats)
        offset = json.loads(one.attrs.get("geometry_json", "{}")).get("offset_mm", 0.0)
        plies.append((ply, index, json.loads((index.parent / "summary.json").read_text()), offset))
    lock = laminate_lock(ds)
    deviation = fibre_deviation(ds)
    mean_dev = deviation.isel({FORCE: 0}).mean(REALIZATION)
    sd_dev = deviation.isel({FORCE: 0}).std(REALIZATION, ddof=1)
    with vector_formats(formats):
        items = [(plot_tool_lock(ds, tool_lock_map(ds), out / "tool_lock_map.png"),
                  "P(any ply locked) on the tool: each raster point takes the locked state of each ply's nearest node")]
        vmax = float(np.nanmax(np.abs(mean_dev.values))) or 1.0
        items.append((plot_ply_maps(ds, mean_dev, out / "fibre_deviation_mean.png",
                                    norm=mpl.colors.Normalize(-vmax, vmax), cmap=mpl.colormaps["RdBu_r"],
                                    label="mean fibre deviation (deg)",
                                    title="fibre-1 plan angle minus the ply's nominal angle: mean"),
                      "mean deviation of each ply's fibre-1 direction from its nominal angle (plan)"))
        if ds.sizes[REALIZATION] > 1:
            top = float(np.nanmax(sd_dev.values)) or 1.0
            items.append((plot_ply_maps(ds, sd_dev, out / "fibre_deviation_sd.png",
                                        norm=mpl.colors.Normalize(0.0, top), cmap=mpl.colormaps["viridis"],
                                        label="sd of fibre deviation (deg)",
                                        title="fibre-1 plan angle minus the ply's nominal angle: sd"),
                          "scatter of each ply's fibre-1 direction (sd over the realisations)"))
    record = {"title": title, "description": description, "plies": {}, "provenance": provenance(wall_time_s),
              "p_any_ply_locked": {f"{float(f):g}": {k: float(lock[k].sel({FORCE: f})) for k in ("p_any", "lower", "upper")}
                                   for f in ds[FORCE].values},
              "confidence": lock.attrs["confidence"], "n": lock.attrs["n"],
              "figures": [path.name for path, _ in items]}
    for ply, index, summary, offset in plies:
        record["plies"][str(ply)] = {
            "angle_deg": float(ds[PLY_ANGLE].sel({PLY: ply})),
            "offset_mm": offset,
            "p_locked": [float(v) for v in lock["p_ply"].sel({PLY: ply}).values],
            "fibre_deviation_mean_max_abs_deg": float(np.nanmax(np.abs(mean_dev.sel({PLY: ply}).values))),
            "fibre_deviation_sd_max_deg": float(np.nanmax(sd_dev.sel({PLY: ply}).values))
            if ds.sizes[REALIZATION] > 1 else None,
            "report": index.relative_to(out).as_posix(),
            **{k: summary[k] for k in ("max_abs_mean_shear_deg", "max_sd_deg", "max_wrinkle_probability")}}
    write_text_atomic(out / "summary.json", json.dumps(record, indent=2, allow_nan=False) + "\n")
    index = out / "index.html"
    write_text_atomic(index, _page(record, items, study_text))
    return index


def _page(record: dict, items, study_text: str | None) -> str:
    """The laminate's HTML page."""
    esc = html.escape
    conf = f"{record['confidence']:.0%}"
    lock_rows = "".join(f"<tr><td>{esc(force)} N</td><td class=\"num\">{v['p_any']:.3g}</td>"
                        f"<td class=\"num\">[{v['lower']:.3g}, {v['upper']:.3g}]</td></tr>"
                        for force, v in record["p_any_ply_locked"].items())
    ply_rows = "".join(
        f"<tr><td><a href=\"{esc(p['report'])}\">{esc(name)}</a></td><td class=\"num\">{p['angle_deg']:+g}</td>"
        f"<td class=\"num\">{p['offset_mm']:g}</td>"
        f"<td class=\"num\">{', '.join(f'{v:.3g}' for v in p['p_locked'])}</td>"
        f"<td class=\"num\">{p['fibre_deviation_mean_max_abs_deg']:.3g}</td>"
        f"<td class=\"num\">{'–' if p['fibre_deviation_sd_max_deg'] is None else format(p['fibre_deviation_sd_max_deg'], '.3g')}</td></tr>"
        for name, p in record["plies"].items())
    body = [f"<h1>{esc(record['title'])}</h1>"]
    if record["description"]:
        body.append(f"<p>{esc(record['description'])}</p>")
    body += [f"<p class=\"note\">{esc(provenance_line(record['provenance']))}</p>",
             f"<h2>Laminate, N = {record['n']}</h2>",
             "<p class=\"note\">Plies are formed one by one over the same tool, without inter-ply friction, each on "
             "the tool's surface offset by the thickness of the plies beneath it (its offset; 0 where no "
             "thickness_mm is given).</p>",
             f"<table><tr><th>blank-holder force</th><th>P(any ply locked)</th><th>{conf} Wilson interval</th></tr>"
             f"{lock_rows}</table>",
             "<table><tr><th>ply</th><th>angle (deg)</th><th>offset (mm)</th><th>P(ply locked) per force level</th>"
             "<th>largest |mean fibre deviation| (deg, plan)</th><th>largest sd of fibre deviation (deg, plan)</th></tr>"
             f"{ply_rows}</table>",
             figures_html(items)]
    if study_text:
        body.append(f"<h2>Study file</h2><pre>{esc(study_text)}</pre>")
    return page(record["title"], "\n".join(body))
