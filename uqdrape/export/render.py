"""A ParaView-style picture of an exported net, drawn from the ``.vtu`` file itself."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from ..files import write_atomic


def render_vtu(net_vtu, png, field: str, *, mould_vtu=None, label: str | None = None, title: str = "",
               view=(32.0, -60.0)) -> Path:
    """Draw the quads of ``net_vtu`` coloured by its point field ``field`` (cell colour:
    mean of its corners), over the grey mould of ``mould_vtu``, and the fibre-1 direction
    at about ten nodes across the net; write ``png`` and return its path. Reads the files with meshio."""
    net = meshio.read(net_vtu)
    quads = net.cells_dict["quad"]
    values = net.point_data[field][quads].mean(1)
    lo, hi = net.points.min(0), net.points.max(0)
    pad = 0.05 * (hi - lo)[:2].max()
    xlim, ylim = (lo[0] - pad, hi[0] + pad), (lo[1] - pad, hi[1] + pad)
    fig = Figure(figsize=(7.5, 6.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d", computed_zorder=False)
    if mould_vtu is not None:
        mould = meshio.read(mould_vtu)
        cells = mould.points[mould.cells_dict["quad"]]
        seen = ((cells[..., 0] >= xlim[0]) & (cells[..., 0] <= xlim[1])
                & (cells[..., 1] >= ylim[0]) & (cells[..., 1] <= ylim[1])).all(-1)
        ax.add_collection3d(Poly3DCollection(cells[seen], facecolor="0.8", edgecolor="none", alpha=0.4, zorder=0))
        lo[2] = min(lo[2], cells[seen][..., 2].min())
    lo_v, hi_v = np.nanpercentile(values, [0.5, 99.5])
    if lo_v < 0 < hi_v:  # a signed field (shear): white at zero
        lo_v, hi_v = -max(-lo_v, hi_v), max(-lo_v, hi_v)
    norm = Normalize(lo_v, hi_v)
    cmap = colormaps["coolwarm"]
    ax.add_collection3d(Poly3DCollection(net.points[quads], facecolors=cmap(norm(values)), edgecolor="k",
                                         linewidth=0.15, zorder=1))
    if "fibre1" in net.point_data and "i" in net.point_data:
        step = max(2, int(np.ptp(net.point_data["i"])) // 10)  # about ten arrows across the net
        pick = (net.point_data["i"] % step == 0) & (net.point_data["j"] % step == 0)
        p, d = net.points[pick], net.point_data["fibre1"][pick]
        length = 0.04 * (hi - lo)[:2].max()
        ax.quiver(*p.T, *(length * d).T, color="k", linewidth=0.8, arrow_length_ratio=0.3, zorder=2)
    ax.set(xlim=xlim, ylim=ylim, zlim=(lo[2], hi[2]), xlabel="x (mm)", ylabel="y (mm)", zlabel="z (mm)")
    ax.set_box_aspect((xlim[1] - xlim[0], ylim[1] - ylim[0], max(hi[2] - lo[2], 1e-6)))
    ax.view_init(*view)
    ax.set_title(title, fontsize=11)
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.6, pad=0.08)
    bar.set_label(label or field)
    return write_atomic(Path(png), lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
