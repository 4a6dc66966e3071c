"""The calibration figure of ``uqdrape calibrate --plot``: the measured points, the fitted
field, a predictive check, the distribution, the profile likelihoods and the families'
criteria, in one PNG the width of a report page's row (``style``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.stats

from ..calibration.fit import profile_curve
from ..calibration.mapping import fibre_coordinates
from .figures import save
from .style import canvas, styled

#: Cells per side of the fitted-field map.
_MAP_CELLS = 60


@styled
def plot_calibration(calibration, path) -> Path:
    """Write the figure of a :class:`~uqdrape.calibration.PointsCalibration` to ``path`` (PNG)."""
    fit = calibration.fit
    points = calibration.points
    level = fit.level
    fig = canvas(17.0, 9.0, layout="constrained")
    axes = fig.subplots(2, 4)
    fig.suptitle(f"Fibre-angle calibration of {Path(points.source).name}: {len(points)} points, {fit.family} field "
                 f"(by {fit.criterion.upper()}), {100 * level:g} % intervals")
    lim = _colour_limits(calibration)
    _points(axes[0, 0], calibration, lim)
    _field(fig, axes[0, 1], calibration, lim)
    _loo(axes[0, 2], calibration)
    _histogram(axes[0, 3], calibration)
    for ax, (name, label) in zip(axes[1, :3], (("sd_deg", "sd σ (deg)"), ("length_1_mm", "L1 along fibre 1 (mm)"),
                                              ("length_2_mm", "L2 along fibre 2 (mm)"))):
        _profile(ax, fit, name, label)
    _criteria(axes[1, 3], fit)
    return save(fig, path)


def _colour_limits(calibration):
    mean = calibration.fit.estimates["mean_deg"].value
    half = float(np.max(np.abs(calibration.gamma0_deg - mean))) or 1.0
    return mean - half, mean + half


def _arrows(ax, calibration):
    """The nominal fibre directions, from the middle of the sample."""
    x, y = calibration.points.x_mm, calibration.points.y_mm
    centre = np.array([x.mean(), y.mean()])
    size = 0.25 * max(np.ptp(x), np.ptp(y), 1.0)
    for k, angle in ((1, calibration.fibre1_deg), (2, calibration.fibre1_deg + 90.0)):
        d = size * np.array([np.cos(np.deg2rad(angle)), np.sin(np.deg2rad(angle))])
        ax.annotate("", xy=centre + d, xytext=centre, arrowprops=dict(arrowstyle="->", color="k", lw=1.2))
        ax.text(*(centre + 1.12 * d), f"fibre {k}", ha="center", va="center")


def _points(ax, calibration, lim):
    p = calibration.points
    marker = np.where(p.fibre_set == 1, "o", "s")
    for m, label in (("o", "set 1"), ("s", "set 2")):
        keep = marker == m
        if keep.any():
            sc = ax.scatter(p.x_mm[keep], p.y_mm[keep], c=calibration.gamma0_deg[keep], cmap="coolwarm",
                            vmin=lim[0], vmax=lim[1], marker=m, edgecolors="k", linewidths=0.4, label=label)
    ax.figure.colorbar(sc, ax=ax, label="γ0 (deg)")
    _arrows(ax, calibration)
    ax.set(title="measured points\nγ0: the fibre's deviation", xlabel="x (mm)", ylabel="y (mm)", aspect="equal")
    ax.legend(loc="lower right")


def _field(fig, ax, calibration, lim):
    """The field's conditional mean given the points, on a grid over their bounding box."""
    p, fit = calibration.points, calibration.fit
    pad = 0.05 * max(np.ptp(p.x_mm), np.ptp(p.y_mm), 1.0)
    gx = np.linspace(p.x_mm.min() - pad, p.x_mm.max() + pad, _MAP_CELLS)
    gy = np.linspace(p.y_mm.min() - pad, p.y_mm.max() + pad, _MAP_CELLS)
    X, Y = np.meshgrid(gx, gy)
    a, b = fibre_coordinates(X.ravel(), Y.ravel(), calibration.fibre1_deg)
    mean, _ = fit.likelihood.predict(fit.chosen.theta, a, b)
    mesh = ax.pcolormesh(gx, gy, mean.reshape(X.shape), cmap="coolwarm", vmin=lim[0], vmax=lim[1], shading="auto")
    ax.scatter(p.x_mm, p.y_mm, s=6, c="k")
    fig.colorbar(mesh, ax=ax, label="γ0 (deg)")
    note = "iid: no structure between points" if fit.family == "iid" else (
        f"L = {fit.chosen.length_mm[0]:.3g}, {fit.chosen.length_mm[1]:.3g} mm")
    ax.set(title=f"fitted field (conditional mean)\n{note}", xlabel="x (mm)", ylabel="y (mm)", aspect="equal")


def loo_check(calibration) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The predictive check of measured points: each point's γ0 predicted from all the
    others (deg), the half-width of its ``level`` band (deg) and whether it lies inside."""
    fit = calibration.fit
    pred, sd = fit.likelihood.leave_one_out(fit.chosen.theta)
    half = scipy.stats.norm.ppf(0.5 + fit.level / 2) * sd
    return pred, half, np.abs(calibration.gamma0_deg - pred) <= half


def _loo(ax, calibration):
    """Each point against its prediction from all the others, with the predictive band."""
    fit = calibration.fit
    y = calibration.gamma0_deg
    pred, half, inside = loo_check(calibration)
    ax.errorbar(pred, y, xerr=half, fmt="none", ecolor="0.7", lw=0.8)
    ax.scatter(pred[inside], y[inside], s=12, c="C0", label="inside")
    ax.scatter(pred[~inside], y[~inside], s=14, c="C3", label="outside")
    span = [min(y.min(), pred.min()), max(y.max(), pred.max())]
    ax.plot(span, span, "k-", lw=0.8)
    ax.set(title=f"predictive check: {inside.sum()} of {len(y)} points inside\nthe {100 * fit.level:g} % "
                 "band predicted from the others",
           xlabel="γ0 predicted from the other points (deg)", ylabel="γ0 measured (deg)")
    ax.legend()


def _histogram(ax, calibration):
    fit = calibration.fit
    y = calibration.gamma0_deg
    ax.hist(y, bins=max(5, int(np.sqrt(len(y)))), density=True, color="0.75", edgecolor="k", lw=0.4)
    mean = fit.estimates["mean_deg"].value
    sd = np.hypot(fit.chosen.sd_deg, fit.chosen.nugget_deg)
    grid = np.linspace(y.min() - sd, y.max() + sd, 200)
    ax.plot(grid, scipy.stats.norm.pdf(grid, mean, sd), "C0-",
            label=f"fitted N({mean:.3g}, {sd:.3g}²)\n(field and nugget)")
    ax.set(title="distribution of γ0", xlabel="γ0 (deg)", ylabel="density")
    ax.legend(loc="upper left")


def _profile(ax, fit, name, label):
    profile = fit.profiles.get(name)
    if profile is None:
        ax.text(0.5, 0.5, f"{fit.family}: no {label.split(' ')[0]}", ha="center", va="center",
                transform=ax.transAxes)
        ax.set(title=f"profile likelihood of {label}", xticks=[], yticks=[])
        return
    estimate = fit.estimates[name]
    values, deviance = profile_curve(fit, name)
    ax.plot(values, deviance, "C0.-")
    lo, hi = profile.cut
    ax.axhline(lo, color="C3", ls=":", lw=0.8)
    if hi != lo:
        ax.axhline(hi, color="C3", ls="--", lw=0.8)
    ax.axvspan(estimate.lower, estimate.upper, color="C0", alpha=0.12)
    ax.axvline(estimate.value, color="k", lw=0.8)
    ends = ("≤" if estimate.lower_open else "") + f"{estimate.lower:.3g}", \
        ("≥" if estimate.upper_open else "") + f"{estimate.upper:.3g}"
    ax.set(title=f"profile likelihood of {label}\n{estimate.value:.3g} [{ends[0]}, {ends[1]}]",
           xlabel=label, ylabel="2 (ℓ̂ − ℓ_profile)", ylim=(0, 1.6 * max(lo, hi)))


def _criteria(ax, fit):
    names = list(fit.fits)
    values = [getattr(fit.fits[n], fit.criterion) for n in names]
    colours = ["C0" if n == fit.family else "0.7" for n in names]
    ax.bar(range(len(names)), np.asarray(values) - min(values), color=colours)
    ax.text(names.index(fit.family), 0.0, "kept", ha="center", va="bottom", color="C0")
    ax.set_xticks(range(len(names)), [n.replace("_", "\n") for n in names])
    ax.set(title=f"{fit.criterion.upper()} − least of the families", ylabel=f"Δ{fit.criterion.upper()}")


@styled
def plot_drape_posterior(samples: dict, lower, upper, level: float, path) -> Path:
    """A corner plot of a drape calibration's posterior ``samples`` (name -> draws) in the
    prior box [lower, upper]: each marginal with its median and ``level`` interval, each
    pair's draws."""
    names = list(samples)
    d = len(names)
    fig = canvas(3.6 * d + 1.0, 3.2 * d + 0.6, layout="constrained")
    axes = np.atleast_2d(fig.subplots(d, d, squeeze=False))
    alpha = 1.0 - level
    for i, row in enumerate(names):
        for j, col in enumerate(names):
            ax = axes[i, j]
            if j > i:
                ax.set_visible(False)
                continue
            if i == j:
                x = samples[row]
                lo, mid, hi = np.quantile(x, [alpha / 2, 0.5, 1 - alpha / 2])
                ax.hist(x, bins=40, range=(lower[i], upper[i]), density=True, color="0.75", edgecolor="k", lw=0.3)
                ax.axvspan(lo, hi, color="C0", alpha=0.15)
                ax.axvline(mid, color="C0")
                ax.set(xlim=(lower[i], upper[i]), yticks=[],
                       title=f"{row}\n{mid:.3g} [{lo:.3g}, {hi:.3g}] ({100 * level:g} %)")
            else:
                ax.plot(samples[col], samples[row], ",", color="C0", alpha=0.3)
                ax.set(xlim=(lower[j], upper[j]), ylim=(lower[i], upper[i]))
                if j == 0:
                    ax.set_ylabel(row)
            if i == d - 1:
                ax.set_xlabel(col)
    fig.suptitle("Posterior of the calibrated parameters (uniform prior on the axes' box)")
    return save(fig, path)


@styled
def plot_drape_predictive(distance, sign, measured, lower, upper, level: float, parts, path) -> Path:
    """The posterior-predictive check of a drape calibration: at each measured point (by
    distance, mm; one panel per quadrant sign) the ``level`` band (lower, upper; deg) of a
    new part's shear and the parts' ``measured`` shears (part, point; NaN where not
    measured), both less the band's centre so that a band of 0.1 deg shows beside a
    shear of 15."""
    fig = canvas(13.0, 4.8, layout="constrained")
    centre = 0.5 * (lower + upper)
    inside = (measured >= lower) & (measured <= upper)
    counted = np.isfinite(measured)
    for ax, s, text in zip(fig.subplots(1, 2), (1.0, -1.0), ("+ quadrants (i·j > 0)", "− quadrants (i·j < 0)")):
        at = np.flatnonzero(sign == s)
        order = at[np.argsort(distance[at])]
        ax.fill_between(distance[order], (lower - centre)[order], (upper - centre)[order], color="C0", alpha=0.25,
                        label=f"{100 * level:g} % posterior-predictive band")
        for j, name in enumerate(parts):
            ax.plot(distance[order], (measured[j] - centre)[order], "o", ms=5, mfc="none", color=f"C{1 + j % 9}",
                    label=name if j < 8 else None)
        n_in, n = int(inside[:, at].sum()), int(counted[:, at].sum())
        ax.set(title=f"{text}: {n_in} of {n} measured points inside", xlabel="distance from the crossover (mm)",
               ylabel="shear − the band's centre (deg)")
        ax.legend()
    fig.suptitle(f"Posterior-predictive check: {int(inside.sum())} of {int(counted.sum())} measured points "
                 f"({100 * inside.sum() / counted.sum():.0f} %) inside the {100 * level:g} % band")
    return save(fig, path)
