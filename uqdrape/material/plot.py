"""Figure of a material's shear force curve N_s(γ) and energy density W(γ)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..files import write_atomic


def _figure(width_in, height_in):
    """A matplotlib Figure on the Agg canvas. matplotlib is imported here, not with the
    material model, so the solver's processes do not pay for it."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path) -> Path:
    """Write ``fig`` to ``path`` atomically, in the format its suffix names (PNG without one)."""
    path = Path(path)
    return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=120, format=path.suffix[1:] or "png"))


def plot_material(material, path):
    """Write a PNG of N_s (N/m) and W (J/m²) against shear angle (deg), -locking..+locking.

    Negative shear is plotted at negative angles with a negative force, as the solver
    sees it; dashed lines mark the locking angles. Returns the path written.
    """
    path = Path(path)
    gamma_deg = np.linspace(-material.locking_angle_neg_deg, material.locking_angle_deg, 601)
    gamma = np.deg2rad(gamma_deg)

    fig = _figure(9.0, 3.8)
    ax_f, ax_w = fig.subplots(1, 2)
    pos, neg = gamma_deg >= 0.0, gamma_deg <= 0.0
    for ax, values, ylabel in (
        (ax_f, material.shear_force(gamma), "normalised shear force $N_s = F_s/L$ (N/m)"),
        (ax_w, material.energy_density(gamma), "shear energy density $W$ (J/m²)"),
    ):
        ax.plot(gamma_deg[pos], values[pos], color="tab:red", label="positive shear")
        ax.plot(gamma_deg[neg], values[neg], color="tab:blue", label="negative shear")
        for lock in (material.locking_angle_deg, -material.locking_angle_neg_deg):
            ax.axvline(lock, color="0.4", linestyle="--", linewidth=1.0)
        ax.axhline(0.0, color="0.8", linewidth=0.8)
        ax.set(xlabel="shear angle γ (deg)", ylabel=ylabel)
        ax.grid(alpha=0.3)
    ax_f.legend(loc="upper left", title="dashed: locking")
    fig.suptitle(f"{material.name}: φ0 = {material.phi0_deg:g}°, locking +{material.locking_angle_deg:g}° / "
                 f"−{material.locking_angle_neg_deg:g}°")
    return _save(fig, path)


def plot_architecture(arch, path, terms=None, gamma0_deg=None):
    """Write a thesis Fig 4.18-style PNG: each term's N_s (N/m) against θ (deg), −75..75.

    Left: the four contributions on the thesis's axes (±200 N/m); right: their sum on an
    axis that fits it (to 1000 N/m), with the zero-force angle γ0 marked. ``terms`` is
    ``uqdrape.material.architecture.summed(arch)`` (computed if None). Returns the path.
    """
    from .architecture import LOCK_FORCE_N_PER_M, TERMS, summed

    path = Path(path)
    terms = summed(arch) if terms is None else terms
    deg = np.rad2deg(terms["theta"])
    fig = _figure(10.0, 4.0)
    ax_t, ax_s = fig.subplots(1, 2)
    colours = {"stitch_tension": "tab:red", "stitch_friction": "tab:orange", "compaction": "tab:blue",
               "crossover": "tab:green", "total": "k"}
    for term in (*TERMS, "total"):
        ax = ax_s if term == "total" else ax_t
        ns = np.where(np.isfinite(terms[f"ns_{term}"]), terms[f"ns_{term}"], np.nan)
        ax.plot(deg, ns, color=colours[term], label=term.replace("_", " "))
    ax_t.set_ylim(-200.0, 200.0)
    total = terms["ns_total"]
    shown = np.abs(total[np.isfinite(total)])
    top = min(LOCK_FORCE_N_PER_M, 1.1 * float(shown.max()))
    ax_s.set_ylim(-top, top)
    if gamma0_deg is not None:
        ax_s.axvline(gamma0_deg, color="0.4", linestyle="--", linewidth=1.0,
                     label=f"zero-force angle {gamma0_deg:.2f}°")
    for ax, title in ((ax_t, "contributions (thesis Fig 4.18 axes)"), (ax_s, "summed")):
        ax.set(xlim=(-75.0, 75.0), xlabel="shear angle θ (deg)", ylabel="normalised shear force $N_s$ (N/m)")
        ax.axhline(0.0, color="0.8", linewidth=0.8)
        ax.axvline(0.0, color="0.8", linewidth=0.8)
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    fig.suptitle(f"{arch.name}: stitch {arch.stitch_length_mm:g} mm, gauge {arch.gauge:g}, lapping "
                 f"{tuple(arch.lapping)}, pre-strain {100 * arch.prestrain:.3g} %, β = {arch.beta:.4g}")
    return _save(fig, path)


def plot_sheartest(result, path):
    """Write a PNG of a card fitted from shear tests (thesis Figs 3.22-3.27 style), one row
    per branch: the raw specimens (the force column, crosshead force (N) or normalised
    F/L or F_s/L (N/m) as the rig file's force_convention says, against displacement (mm); rows
    not fitted, the friction jump and past the valid end, in grey); each
    specimen's rows normalised to N_s (N/m) with its fit; the card's mean and its ±1 sd
    band (bias extension: also the thesis's iterative route, Eq 3.34-3.35, on the same
    fits). ``result`` is a `uqdrape.material.sheartest.CardFit`. Returns the path."""
    path = Path(path)
    shear, scatter = result.doc["shear"], result.doc.get("scatter", {})
    record = result.doc["sheartest"]
    convention = record["force_convention"]
    column = "crosshead force (N)" if convention == "crosshead" else f"force column {convention} (N/m)"
    ns_label = "normalised shear force $N_s = F_s/L$ (N/m)"
    branches = list(shear)
    fig = _figure(13.0, 3.9 * len(branches))
    axes = np.atleast_2d(fig.subplots(len(branches), 3))
    colours = [f"C{i}" for i in range(10)]
    for row, branch in zip(axes, branches):
        ax_raw, ax_pts, ax_card = row
        fits = [f for f in result.fits if f.specimen.branch == branch]
        for i, f in enumerate(fits):
            colour, data = colours[i % 10], f.specimen.data
            ax_raw.plot(data.displacement_mm[~f.used], data.force_n[~f.used], ".", ms=1.5, color="0.75")
            ax_raw.plot(data.displacement_mm[f.used], data.force_n[f.used], ".", ms=1.5, color=colour,
                        label=data.path.name)
            theta, ns = f.points()
            ax_pts.plot(np.rad2deg(theta), ns, ".", ms=1.5, color=colour, alpha=0.4)
            grid = np.linspace(0.0, f.end, 200)
            ax_pts.plot(np.rad2deg(grid), f.shear_force(grid), color=colour, lw=1.2,
                        label=f"{data.path.name}: fit to {np.rad2deg(f.end):.1f}° ({f.end_rule})")
        angles, mean = np.asarray(shear[branch]["angle_deg"]), np.asarray(shear[branch]["ns"])
        ax_card.plot(angles, mean, color="k", lw=1.5, label=f"card: mean of {len(fits)}")
        if branch in scatter:
            sd = np.asarray(scatter[branch]["ns_sd"])
            ax_card.fill_between(angles, mean - sd, mean + sd, color="0.6", alpha=0.4, label="±1 sd of the specimens")
        if record["test"] == "bias_extension" and convention == "crosshead":
            theta = np.deg2rad(angles)
            thesis = np.mean([f.specimen.rig.thesis_iterative(f.force, theta) for f in fits], axis=0)
            ax_card.plot(angles, thesis, "--", color="tab:red", lw=1.0, label="thesis route (Eq 3.34-3.35)")
        ax_raw.set(xlabel="crosshead displacement (mm)", ylabel=column,
                   title=f"{branch} shear: raw specimens (grey: not fitted)")
        ax_pts.set(xlabel="shear angle θ (deg)", ylabel=ns_label,
                   title="normalised rows and monotone fits")
        ax_card.set(xlabel="shear angle θ (deg)", ylabel=ns_label,
                    title="card")
        for ax in row:
            ax.grid(alpha=0.3)
            ax.legend(loc="upper left", fontsize=7, markerscale=4)
    fig.suptitle(f"{result.doc['name']}: {record['test'].replace('_', ' ')} tests, friction {record['friction']}, "
                 f"φ0 = {result.doc['phi0_deg']:g}°\nforce column: {convention}; {record['normalisation']}")
    return _save(fig, path)
