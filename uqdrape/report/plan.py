"""The report plan: which figures a study's report has, decided from what the study is.

Each :class:`Spec` names the study kinds it applies to (``uqdrape.stats.STUDY_KINDS``: random
sample, deterministic, swept factor, sensitivity sample) and a predicate on the data;
:func:`render` walks :data:`PLAN` in order and draws what applies. A spec whose kind
applies but whose data does not (e.g. a wrinkle-risk map where no node ever locks) may
give a sentence for the page instead of a figure. Decisions:

- histograms with a Normal fit, convergence with N and the wrinkle-risk map with its
  binomial interval need independent draws: random samples only;
- the sd map is descriptive, so a sensitivity sample has it too;
- a swept factor is shown against the factor (``vs_<factor>.png``), not as a distribution;
- a blank-holder force sweep gets its line means against force whatever the kind.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import xarray as xr

from uqdrape.schema import FORCE, REALIZATION
from uqdrape.stats import STUDY_KINDS, line_statistics, varying_factors
from uqdrape.stats.headline import SENSITIVITY, DETERMINISTIC, RANDOM, SWEPT

from . import ensemble_figures
from .figures import plot_lines, plot_net
from .sensitivity_figures import INDICES, plot_sensitivity_bars, plot_sensitivity_map, plot_sensitivity_vs_force


@dataclass(frozen=True)
class Context:
    """What the figures of one report are drawn from: the ensemble (in the ensemble layout), its kind, the
    statistics computed once, the output folder and the caller's options."""

    ds: xr.Dataset
    kind: str
    out: Path
    node_stats: xr.Dataset
    exceedance: xr.Dataset | None
    histogram_nodes: Sequence[Sequence[int]]
    experimental: object = None
    sensitivity: xr.Dataset | None = None
    sensitivity_maps: xr.Dataset | None = None


@dataclass(frozen=True)
class Spec:
    """One figure of the plan: the kinds it applies to, ``when`` the data has what it
    shows, ``draw`` -> [(png path, caption)], and ``otherwise`` -> a sentence for the page
    when the kind applies but ``when`` fails (None: leave it out silently)."""

    name: str
    kinds: tuple[str, ...]
    draw: Callable[[Context], list[tuple[Path, str]]]
    when: Callable[[Context], bool] = lambda c: True
    otherwise: Callable[[Context], str] | None = None


def _net(c: Context):
    return [(plot_net(c.ds, c.out / "net.png"),
             "Draped net of the first realisation" + (" at each blank-holder force" if c.ds.sizes[FORCE] > 1 else "")
             + ", cells coloured by node shear (deg) on one colour scale.")]


def _lines(c: Context):
    measured = ", with the measured points" if c.experimental is not None else ""
    return [(plot_lines(c.ds, c.out / "lines.png", experimental=c.experimental),
             f"Shear along the four max-shear lines of the first realisation (red: i·j > 0 quadrants, blue: the "
             f"others){measured}.")]


def _vs_factor(c: Context):
    factor = varying_factors(c.ds)[0]
    return [(ensemble_figures.plot_scalar_vs_factor(c.ds, c.out / f"vs_{factor}.png", factor),
             f"Blank-holder energy per quadrant and in total, and the max-shear line means, of each drape against "
             f"{factor} (thesis Fig 5.6 for the skew).")]


def _sweep(c: Context):
    spread = " (mean ± 1 sd over the realisations)" if c.ds.sizes[REALIZATION] > 1 else ""
    return [(ensemble_figures.plot_sweep(c.ds, c.out / "sweep.png"),
             f"Mean shear of the + and − quadrant max-shear lines and their asymmetry against blank-holder "
             f"force{spread}.")]


def _mean(c: Context):
    text = ("Node shear on the node positions." if c.kind == DETERMINISTIC else
            "Mean node shear on the mean node positions" + (" over the sample's evaluations." if c.kind == SENSITIVITY
                                                            else "."))
    return [(ensemble_figures.plot_mean_map(c.ds, c.out / "mean_shear.png", node_stats=c.node_stats), text)]


def _sd(c: Context):
    return [(ensemble_figures.plot_sd_map(c.ds, c.out / "sd_shear.png", node_stats=c.node_stats),
             "Standard deviation of node shear on the mean node positions"
             + (" over the sample's evaluations (descriptive: the sensitivity sample is not a random sample)."
                if c.kind == SENSITIVITY else "."))]


def _has_risk(c: Context) -> bool:
    return c.exceedance is not None and bool((c.exceedance["probability"] > 0).any())


def _no_risk(c: Context) -> str:
    if c.exceedance is None:
        return "No wrinkle-risk map: the drapes have no locking angle (a geodesic drape without a material)."
    upper = float(c.exceedance["probability_upper"].max())
    return (f"No wrinkle-risk map: no node sits next to a locked cell in any of the {c.ds.sizes[REALIZATION]} "
            f"realisations (the {c.exceedance.attrs['confidence']:.0%} upper limit of the risk is "
            f"{upper:.3f} or less at every node).")


def _wrinkle(c: Context):
    ex = c.exceedance
    return [(ensemble_figures.plot_wrinkle_map(c.ds, c.out / "wrinkle_risk.png", exceedance=ex),
             f"Wrinkle risk {ex.attrs['risk']} per node (a cell locks past its own branch's locking angle); the "
             f"node of highest risk is marked with its {ex.attrs['confidence']:.0%} {ex.attrs['interval']}.")]


def _line_statistics(c: Context):
    return [(ensemble_figures.plot_line_statistics(c.ds, c.out / "line_statistics.png", line_stats=line_statistics(c.ds),
                                  experimental=c.experimental),
             "Shear against distance from the crossover along the max-shear lines: mean ± 1 sd per node and the "
             "band holding the central 95 % of realisations (thesis Figs 5.18/5.19).")]


def _histograms(c: Context):
    return [(ensemble_figures.plot_histograms(c.ds, c.out / "histograms.png", c.histogram_nodes),
             "Histograms of node shear with the fitted Normal (thesis Fig 5.20), each level on its own bins.")]


def _has_spread(c: Context) -> bool:
    return bool((c.node_stats["sd"] > 0).any())


def _no_spread(c: Context) -> str:
    return (f"No histograms or convergence plot: node shear is the same in all {c.ds.sizes[REALIZATION]} "
            "realisations (no random input of the study changed any drape).")


def _convergence(c: Context):
    return [(ensemble_figures.plot_convergence(c.ds, c.out / "convergence.png", node_stats=c.node_stats),
             "Convergence of the mean shear with N at the most variable node.")]


def _ci(c: Context) -> str:
    return f"{100 * c.sensitivity.attrs['conf_level']:g} % bootstrap confidence intervals"


def _sensitivity_bars(c: Context):
    return [(plot_sensitivity_bars(c.sensitivity, c.out / "sensitivity_bars.png"),
             f"Sensitivity indices of each quantity of interest (rows) per blank-holder level (columns), "
             f"with {_ci(c)} as error bars.")]


def _sensitivity_vs_force(c: Context):
    return [(plot_sensitivity_vs_force(c.sensitivity, c.out / "sensitivity_vs_force.png"),
             f"Indices of each factor against blank-holder force, bands: {_ci(c)}.")]


def _sensitivity_maps(c: Context):
    return [(plot_sensitivity_map(c.ds, c.sensitivity_maps, c.out / f"sensitivity_map_{var}.png", index=var),
             f"{name} of node shear per factor (rows) and blank-holder level (columns), on the mean net; blank "
             "where a node is invalid in some evaluation.")
            for var, _, name in INDICES[c.sensitivity.attrs["method"]]]


ALL = STUDY_KINDS
#: The figures of the Sensitivity section, drawn first on a sensitivity sample's page.
SENSITIVITY_PLAN = (
    Spec("sensitivity_vs_force", (SENSITIVITY,), _sensitivity_vs_force,
         when=lambda c: c.sensitivity is not None and c.sensitivity.sizes[FORCE] > 1),
    Spec("sensitivity_bars", (SENSITIVITY,), _sensitivity_bars, when=lambda c: c.sensitivity is not None),
    Spec("sensitivity_maps", (SENSITIVITY,), _sensitivity_maps, when=lambda c: c.sensitivity_maps is not None),
)
#: The other figures, in page order.
PLAN = (
    Spec("net", ALL, _net),
    Spec("lines", ALL, _lines),
    Spec("vs_factor", (RANDOM, SWEPT), _vs_factor,
         when=lambda c: c.ds.sizes[FORCE] == 1 and len(varying_factors(c.ds)) == 1),
    Spec("sweep", ALL, _sweep, when=lambda c: c.ds.sizes[FORCE] > 1),
    Spec("mean_shear", (RANDOM, DETERMINISTIC, SENSITIVITY), _mean),
    Spec("sd_shear", (RANDOM, SENSITIVITY), _sd),
    Spec("wrinkle_risk", (RANDOM,), _wrinkle, when=_has_risk, otherwise=_no_risk),
    Spec("line_statistics", (RANDOM,), _line_statistics),
    Spec("histograms", (RANDOM,), _histograms, when=_has_spread, otherwise=_no_spread),
    Spec("convergence", (RANDOM,), _convergence, when=_has_spread),
)


def render(plan: Sequence[Spec], c: Context) -> list[tuple[Path, str] | str]:
    """Draw the specs of ``plan`` that apply to ``c``: [(png path, caption)], with a
    sentence (str) in place of a figure whose data is missing."""
    items: list[tuple[Path, str] | str] = []
    for spec in plan:
        if c.kind not in spec.kinds:
            continue
        if spec.when(c):
            items += spec.draw(c)
        elif spec.otherwise is not None:
            items.append(spec.otherwise(c))
    return items
