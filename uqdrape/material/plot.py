"""Figure of a material's shear force curve N_s(γ) and energy density W(γ)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def plot_material(material, path):
    """Write a PNG of N_s (N/m) and W (J/m²) against shear angle (deg), -locking..+locking.

    Negative shear is plotted at negative angles with a negative force, as the solver
    sees it; dashed lines mark the locking angles. Returns the path written.
    """
    path = Path(path)
    gamma_deg = np.linspace(-material.locking_angle_neg_deg, material.locking_angle_deg, 601)
    gamma = np.deg2rad(gamma_deg)

    fig = Figure(figsize=(9.0, 3.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax_f, ax_w = fig.subplots(1, 2)
    pos, neg = gamma_deg >= 0.0, gamma_deg <= 0.0
    for ax, values, ylabel in (
        (ax_f, material.shear_force(gamma), "normalised shear force $N_s$ (N/m)"),
        (ax_w, material.energy_density(gamma), "shear energy density $W$ (J/m²)"),
    ):
        ax.plot(gamma_deg[pos], values[pos], color="tab:red", label="positive shear")
        ax.plot(gamma_deg[neg], values[neg], color="tab:blue", label="negative shear")
        for lock in (material.locking_angle_deg, -material.locking_angle_neg_deg):
            ax.axvline(lock, color="0.4", linestyle="--", linewidth=1.0)
        ax.axhline(0.0, color="0.8", linewidth=0.8)
        ax.set_xlabel("shear angle γ (deg)")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    ax_f.legend(loc="upper left", title="dashed: locking")
    fig.suptitle(f"{material.name}: φ0 = {material.phi0_deg:g}°, locking +{material.locking_angle_deg:g}° / "
                 f"−{material.locking_angle_neg_deg:g}°")
    fig.savefig(path, dpi=120)
    return path
