"""Figures of single drapes: the draped net in 3-D and shear along the max-shear lines.

Every figure is drawn on a ``matplotlib.figure.Figure`` with the Agg canvas (no pyplot,
no screen, no global state), written as a PNG and its path returned. Every figure
function takes its Dataset in the ensemble layout (``uqdrape.schema.by_force``: one panel
or line per blank-holder level, titled with its force), a drape Dataset being put in it
first. The helpers at the top (style, panels, labels, levels) are shared with the other
figure modules.
"""

from __future__ import annotations

import functools
import io
import math
import textwrap
from pathlib import Path

import matplotlib as mpl
import numpy as np
import xarray as xr
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from PIL import Image

from uqdrape.drape.lines import max_shear_lines
from uqdrape.schema import FORCE, QUADRANTS, REALIZATION, by_force, site_dims

from ..experimental import as_experimental
from ..files import write_atomic
from .style import DPI, canvas, requested_formats, styled

#: Line style per max-shear quadrant: i*j > 0 (positive-shear) quadrants red, the others blue.
QUADRANT_STYLE = {
    "++": dict(color="tab:red", marker="o", linestyle="-"),
    "--": dict(color="tab:red", marker="s", linestyle="--"),
    "-+": dict(color="tab:blue", marker="^", linestyle="-"),
    "+-": dict(color="tab:blue", marker="v", linestyle="--"),
}
PLUS_COLOR, MINUS_COLOR = "tab:red", "tab:blue"
#: The lines start at the crossover (the tip of a dome or cone, the centre of a plate).
DISTANCE_LABEL = "distance from the crossover (mm)"
SHEAR_LABEL = "shear angle γ (deg)"


def report_figure(func):
    """A figure function ``func(ds, ...)`` of an ensemble: :func:`styled`, with ``ds`` in
    the ensemble layout (``uqdrape.schema.by_force``)."""
    @styled
    @functools.wraps(func)
    def wrapper(ds, *args, **kwargs):
        return func(by_force(ds), *args, **kwargs)
    return wrapper


def panels(n: int, *, size=(5.4, 4.2), max_cols: int = 4, cols: int | None = None, **subplot_kw):
    """A constrained-layout Figure with ``n`` panels of about ``size`` (in; the figure is
    scaled to a column's or the row's width, ``style.canvas``), ``cols`` per row (default:
    a near-square grid of at most ``max_cols``); returns (fig, axes list)."""
    cols = cols or (n if n <= 3 else min(max_cols, math.ceil(math.sqrt(n))))
    rows = math.ceil(n / cols)
    fig = canvas(size[0] * cols, size[1] * rows, layout="constrained")
    axes = [fig.add_subplot(rows, cols, k + 1, **subplot_kw) for k in range(n)]
    return fig, axes


def shared_ylim(axes) -> None:
    """Give every panel the union of their y ranges, so levels compare at a glance."""
    lows, highs = zip(*(ax.get_ylim() for ax in axes))
    for ax in axes:
        ax.set_ylim(min(lows), max(highs))


def save(fig: Figure, path) -> Path:
    """Write ``fig`` as a lossless RGB PNG at ``path`` (parent folders created), and in
    the vector formats requested (``style.vector_formats``) beside it; return the PNG's Path.

    The figure is opaque, so dropping matplotlib's alpha channel loses nothing and makes
    the file about 85 % of matplotlib's RGBA one, with none of the banding a palette image
    gives colour bars. zlib's default level: Pillow's ``optimize`` made the gallery's PNGs
    only 1-4 % smaller for 3-5 times the encoding time (measured on six report figures).
    In a vector file the dense colour fields (artists drawn ``rasterized``) are images at
    ``DPI``; axes, lines and text stay vectors, the text as text.
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"path must end in .png, got {str(path)!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI)
    with Image.open(buffer) as image:
        write_atomic(path, lambda tmp: image.convert("RGB").save(tmp, format="png"))
    for fmt in requested_formats():
        write_atomic(path.with_suffix(f".{fmt}"), lambda tmp, fmt=fmt: fig.savefig(tmp, format=fmt, dpi=DPI))
    return path


def unit_text(units: str | None) -> str:
    """CF unit string -> axis-label text ("degree" -> "deg", "1" -> "-")."""
    return {"degree": "deg", "degrees": "deg", "1": "-", None: "-", "": "-"}.get(units, units)


def label(da: xr.DataArray, fallback: str | None = None) -> str:
    """Axis/colour-bar label "long name (units)" from CF attrs."""
    name = fallback or da.attrs.get("long_name", da.name)
    return f"{name} ({unit_text(da.attrs.get('units'))})"


def force_title(force) -> str:
    return f"F_BH = {float(force):g} N"


def force_groups(ds: xr.Dataset) -> list:
    """[(force N, Dataset at that level)] over the ``blankholder_force`` dim."""
    return [(float(f), ds.sel({FORCE: f})) for f in ds[FORCE].values]


def check_realization(ds: xr.Dataset, realization) -> int:
    """Check ``realization`` is a valid position along ``realization``; return it as int."""
    if REALIZATION not in ds.dims:
        raise ValueError(f"the Dataset has no {REALIZATION!r} dim (dims: {dict(ds.sizes)})")
    size = ds.sizes[REALIZATION]
    if isinstance(realization, bool) or not isinstance(realization, (int, np.integer)) \
            or not 0 <= realization < size:
        raise ValueError(f"realization must be a position 0..{size - 1} along {REALIZATION!r}, got {realization!r}")
    return int(realization)


def describe(ds: xr.Dataset) -> str:
    """Short description of a drape Dataset for figure titles: the mould as its ``mould``
    attribute names it (``Surface.describe``), the material card and the drape mode, e.g.
    "nose cone (base radius 225 mm, ...), ebxhd936_like, energy drape"."""
    geometry = ds.attrs.get("mould")
    mode = ds.attrs.get("mode")
    parts = [geometry, ds.attrs.get("material"), f"{mode} drape" if mode else None]
    return ", ".join(str(p) for p in parts if p not in (None, "", "none"))


def suptitle(fig: Figure, head: str, detail: str = "") -> None:
    """Figure title "head: detail" on one line if it fits the figure's width (about 0.55
    em a character), else the detail on the next line; a part wider than the figure (a
    narrow grid of panels) is wrapped at words rather than clipped."""
    size = mpl.font_manager.FontProperties(size=mpl.rcParams["figure.titlesize"]).get_size_in_points()
    width = int(fig.get_figwidth() * 72 / (0.55 * size))
    if len(head) + len(detail) + 2 <= width or not detail:
        fig.suptitle(textwrap.fill(f"{head}: {detail}" if detail else head, width))
    else:
        fig.suptitle(f"{textwrap.fill(head, width)}\n{textwrap.fill(detail, width)}")


def signed_norm(values: np.ndarray, units: str | None):
    """(norm, cmap): diverging and centred on 0 for angles or signed data, else sequential."""
    finite = values[np.isfinite(values)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    if units in ("degree", "degrees") or lo < 0:
        vmax = max(abs(lo), abs(hi)) or 1.0
        return mpl.colors.Normalize(-vmax, vmax), mpl.colormaps["RdBu_r"]
    return mpl.colors.Normalize(lo, hi if hi > lo else lo + 1.0), mpl.colormaps["viridis"]


def _net_cells(one: xr.Dataset, var: str, site):
    """(quads (2n, 2n, 4, 3) in mm, cell values, mask of drawable cells) of one drape."""
    P = np.stack([one[c].transpose("i", "j").values for c in ("x", "y", "z")], axis=-1)
    quads = np.stack([P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]], axis=2)
    values = one[var].transpose(*site).values.astype(float)
    if site == ("i", "j"):
        values = np.mean(np.stack([values[:-1, :-1], values[1:, :-1], values[1:, 1:], values[:-1, 1:]]), axis=0)
    return quads, values, np.isfinite(quads).all(axis=(2, 3)) & np.isfinite(values)


@report_figure
def plot_net(ds: xr.Dataset, path, var: str = "shear", realization: int = 0, title: str | None = None) -> Path:
    """Draw a draped net in 3-D, cells coloured by ``var``, and write a PNG.

    ``ds`` is a drape or ensemble Dataset: one panel per blank-holder level, titled with its force, on one shared colour scale, so levels
    compare at a glance. ``realization`` is a position along ``realization``. Cells are
    the quads between valid nodes (fibre lines are their edges); a node variable (e.g.
    shear) colours a cell by the mean of its four corners, a cell variable (e.g.
    cell_shear) directly. Angles get a diverging colour map centred on 0 with a colour
    bar in deg. Axes are x, y, z in mm with equal scales. Returns the path.
    """
    if var not in ds.data_vars:
        raise ValueError(f"var={var!r} is not a data variable; valid: {sorted(map(str, ds.data_vars))}")
    missing = [v for v in ("x", "y", "z") if v not in ds.data_vars]
    if missing:
        raise ValueError(f"plot_net needs node positions x, y, z; missing {missing}")
    r = check_realization(ds, realization)
    site = site_dims(ds[var])
    extra = [d for d in (*ds["x"].dims, *ds[var].dims) if d not in ("i", "j", REALIZATION, FORCE, *site)]
    if extra:
        raise ValueError(f"plot_net draws one net per blank-holder level; the Dataset also has dims "
                         f"{sorted(set(extra))}: select one first, e.g. ds.sel({extra[0]}=...)")
    nets = [(force, _net_cells(level[["x", "y", "z", var]].isel({REALIZATION: r}), var, site))
            for force, level in force_groups(ds)]
    drawn = np.concatenate([values[keep] for _, (_, values, keep) in nets])
    if not drawn.size:
        raise ValueError(f"realization {r} has no cell with four valid nodes and a finite {var!r}; nothing to draw")
    norm, cmap = signed_norm(drawn, ds[var].attrs.get("units"))
    fig, axes = panels(len(nets), size=(7.0, 5.6) if len(nets) == 1 else (5.6, 4.6), max_cols=2,
                       projection="3d")
    for ax, (force, (quads, values, keep)) in zip(axes, nets):
        ax.add_collection3d(Poly3DCollection(quads[keep], facecolors=cmap(norm(values[keep])),
                                             edgecolors="0.15", linewidths=0.35 if quads.shape[0] <= 40 else 0.15,
                                             rasterized=True))
        pts = quads[keep].reshape(-1, 3)
        lo, span = pts.min(axis=0), np.maximum(np.ptp(pts, axis=0), 1e-6)
        span[2] = max(span[2], 0.05 * span[:2].max())
        ax.set(xlim=(lo[0], lo[0] + span[0]), ylim=(lo[1], lo[1] + span[1]), zlim=(lo[2], lo[2] + span[2]),
               xlabel="x (mm)", ylabel="y (mm)", zlabel="z (mm)")
        ax.set_box_aspect(tuple(span))
        ax.locator_params(nbins=4)  # more ticks run into each other on the slanted axes
        ax.view_init(elev=32, azim=-60)
        n_bad = int((~keep).sum())
        ax.set_title(force_title(force) + (f", {n_bad} cells not drawn" if n_bad else ""))
    fig.colorbar(mpl.cm.ScalarMappable(norm=norm, cmap=cmap), ax=axes, shrink=0.6, pad=0.06, label=label(ds[var]))
    suptitle(fig, title or f"draped net, realisation {int(ds[REALIZATION][r])}", "" if title else describe(ds))
    return save(fig, path)


def _line_panels(ds: xr.Dataset, realization):
    """[(force, Dataset over the realisations drawn in that panel)] of an ensemble-layout ``ds``."""
    if realization is None:
        return force_groups(ds)
    return [(f, sub.isel({REALIZATION: [check_realization(sub, realization)]})) for f, sub in force_groups(ds)]


def overlay_experimental(ax, points, force) -> None:
    """Scatter measured points (+ quadrants red, - quadrants blue, black edges) on a line plot."""
    if points is None:
        return
    pts = points.at_force(force)
    for sign, color, text in ((1.0, PLUS_COLOR, "+"), (-1.0, MINUS_COLOR, "−")):
        sel = pts.quadrant_sign == sign
        if sel.any():
            ax.scatter(pts.distance_mm[sel], pts.shear_deg[sel], marker="D", s=30, facecolor=color,
                       edgecolor="black", linewidth=0.8, zorder=5,
                       label=f"experiment, {text} quadrants ({pts.source})")


@report_figure
def plot_lines(ds: xr.Dataset, path, realization: int | None = 0, experimental=None) -> Path:
    """Shear (deg) against distance from the crossover (mm) along the four max-shear lines (thesis Fig 5.9).

    Quadrants with i*j > 0 (++, --) are red, the others (-+, +-) blue. One panel per
    blank-holder force level (a drape batch of several forces: one per distinct force, as
    in the thesis). ``realization`` is the position of the drape drawn within each panel's
    realisations (None: all of them, thin). ``experimental`` (a CSV path, see
    ``uqdrape.experimental``) overlays measured points. Returns the path.
    """
    points = as_experimental(experimental)
    groups = _line_panels(ds, realization)
    fig, axes = panels(len(groups), size=(5.6, 4.4))
    for ax, (force, sub) in zip(axes, groups):
        lines = max_shear_lines(sub).transpose(REALIZATION, "quadrant", "k")
        many = lines.sizes[REALIZATION] > 1
        for q in QUADRANTS:
            style = QUADRANT_STYLE[q]
            for r in range(lines.sizes[REALIZATION]):
                line = lines.sel(quadrant=q).isel({REALIZATION: r})
                ax.plot(line["distance"].values, line["shear"].values, color=style["color"],
                        linestyle=style["linestyle"], marker=None if many else style["marker"],
                        markersize=4, linewidth=0.8 if many else 1.5, alpha=0.6 if many else 1.0,
                        label=None if r else f"{q} ({'+' if q in ('++', '--') else '−'} quadrant)")
        overlay_experimental(ax, points, force)
        ax.axhline(0.0, color="0.6", linewidth=0.8)
        ax.set(xlabel=DISTANCE_LABEL, ylabel=SHEAR_LABEL)
        ax.grid(alpha=0.3)
        ax.set_title(force_title(force))
        ax.legend(loc="best")
    shared_ylim(axes)
    suptitle(fig, "shear along the max-shear lines", describe(ds))
    return save(fig, path)
