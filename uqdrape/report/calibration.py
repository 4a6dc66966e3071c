"""The calibration report: one HTML page (the shared skeleton, ``page.py``) of a
calibration's figures, its headline numbers, its warnings and the study block or study it
wrote, for ``uqdrape calibrate ... --report DIR``: :func:`points_page` for measured fibre
angles, :func:`drapes_page` for measured drapes. The figures are drawn by
``uqdrape.report.calibration_figure``; this module only lays them out."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from ..calibration.block import unidentified
from ..calibration.drapes import posterior_dataset
from ..calibration.posterior import prior_box
from ..files import write_text_atomic
from .calibration_figure import loo_check, plot_calibration, plot_drape_posterior, plot_drape_predictive
from .page import figures_html, page, provenance, provenance_line


def calibration_page(folder, title: str, rows, figures, written: str, warnings=(), *, seconds=None) -> Path:
    """Write ``folder/index.html``: ``rows`` (label, value) as the headline table,
    ``warnings`` as sentences above it, ``figures`` ((PNG path, caption) beside the page)
    and ``written`` (the TOML the calibration wrote, comments included). Returns the page."""
    esc = html.escape
    folder = Path(folder)
    table = "".join(f"<tr><th>{esc(label)}</th><td class=\"num\">{esc(value)}</td></tr>" for label, value in rows)
    alerts = "".join(f"<p><b>Warning:</b> {esc(w)}</p>\n" for w in warnings)
    body = (f"<h1>{esc(title)}</h1>\n<p class=\"note\">{esc(provenance_line(provenance(seconds)))}</p>\n{alerts}"
            f"<table>{table}</table>\n<h2>Figures</h2>\n{figures_html(figures)}\n"
            f"<h2>What it wrote</h2>\n<pre>{esc(written)}</pre>")
    return write_text_atomic(folder / "index.html", page(title, body))


def drapes_page(cal, lower, upper, fraction: float, folder: Path, written: str, seconds: float) -> Path:
    """The report of a calibration from measured drapes ``cal`` (a
    ``calibration.drapes.DrapeCalibration``; ``lower``, ``upper`` its predictive band, deg,
    ``fraction`` the measured points inside it), ``written`` the study it wrote."""
    data = posterior_dataset(cal, lower, upper)
    level = 100 * cal.level
    posterior = plot_drape_posterior(cal.posterior.samples, data["prior_lower"].values, data["prior_upper"].values,
                                     cal.level, folder / "posterior.png")
    check = plot_drape_predictive(cal.distance_mm, cal.quadrant_sign, data["measured"].values, lower, upper,
                                  cal.level, list(data["part"].values), folder / "predictive.png")
    rows = [("measured parts", ", ".join(str(p) for p in data["part"].values)),
            ("distinct measured points", str(len(cal.distance_mm))),
            ("measurement sd", f"{cal.likelihood.parts.measurement_sd:g} deg"),
            ("training points (Latin hypercube)", f"{len(cal.runs.points)} points x {cal.runs.shear.shape[1] // 2} drapes"),
            *[(p.key, f"{np.median(cal.posterior.samples[p.key]):.4g} [{cal.interval(p)[0]:.4g}, "
                      f"{cal.interval(p)[1]:.4g}] ({level:g} %), prior [{p.lower:g}, {p.upper:g}]")
              for p in cal.params],
            ("sampler", f"emcee, acceptance {cal.posterior.acceptance:.2f}, {cal.posterior.seconds:.1f} s"),
            ("posterior-predictive check", f"{100 * fraction:.0f} % of the measured points inside the {level:g} % band")]
    figures = [(posterior, f"Posterior of {', '.join(p.key for p in cal.params)}: marginals with median and "
                           f"{level:g} % interval, pairs below"),
               (check, f"Measured shear against the {level:g} % posterior-predictive band of a new part")]
    return calibration_page(folder, "Calibration from measured drapes", rows, figures, written, cal.unidentified(),
                            seconds=seconds)


def points_page(calibration, folder: Path, written: str) -> Path:
    """The report of measured fibre angles ``calibration`` (a
    ``calibration.PointsCalibration``): the calibration figure (points, fitted field,
    leave-one-out predictive check, profiles) and, if sampled, the posterior; ``written``
    the study block it wrote."""
    fit, post = calibration.fit, calibration.posterior
    level = 100 * fit.level
    figures = [(plot_calibration(calibration, folder / "calibration.png"),
                f"Measured points (γ0), the fitted field, each point against its {level:g} % band predicted from "
                "the others (the count inside in the title), the profile likelihoods and the families' criteria")]
    rows = [("measured points", f"{len(calibration.points)} ({Path(calibration.points.source).name})"),
            ("family", f"{fit.family} (least {fit.criterion.upper()})"),
            *[(name, f"{e.value:.4g} [{e.lower:.4g}, {e.upper:.4g}] ({level:g} % profile)")
              for name, e in fit.estimates.items() if name != "nugget_deg"]]
    inside = loo_check(calibration)[2]
    rows.append(("predictive check", f"{inside.sum()} of {inside.size} points ({100 * inside.mean():.0f} %) inside the "
                                     f"{level:g} % band predicted from the others"))
    if post is not None:
        box = prior_box(fit)
        logs = {name: np.log10(draws) for name, draws in post.samples.items()}
        figures.append((plot_drape_posterior({f"log10 {n}": v for n, v in logs.items()},
                                             [np.log10(box[n][0]) for n in logs], [np.log10(box[n][1]) for n in logs],
                                             fit.level, folder / "posterior.png"),
                        "Posterior (emcee) of the field's parameters, log10 on the prior's whole box"))
        rows += [(f"{name}, posterior", f"[{lo:.4g}, {hi:.4g}] ({level:g} %)")
                 for name in post.samples for lo, hi in [post.interval(name, fit.level)]]
    return calibration_page(folder, "Fibre-angle calibration", rows, figures, written, unidentified(calibration),
                            seconds=None if post is None else post.seconds)
