"""uqdrape.report: matplotlib figures (PNG, Agg backend) and an HTML page per study.

Single drapes: ``plot_net`` (3-D net coloured by shear), ``plot_lines`` (shear along the
max-shear lines, thesis Fig 5.9). Ensembles: node maps of the mean, sd and wrinkle
risk, line statistics (Figs 5.18/5.19), histograms (Fig 5.20), convergence, and
blank-holder force sweeps, and per-realisation energies and line means against one
sampled factor (Fig 5.6). Sensitivity runs: index bars, indices against blank-holder
force and index maps of node shear. ``write_report`` writes the figures of the study
kind's plan (``plan.PLAN``) with ``index.html`` and ``summary.json``; the numbers come
from ``uqdrape.stats``, this package only renders.
"""

from .ensemble_figures import (plot_convergence, plot_histograms, plot_line_statistics, plot_mean_map,
                               plot_scalar_vs_factor, plot_sd_map, plot_sweep, plot_wrinkle_map)
from .design import write_design_report
from ..experimental import ExperimentalPoints, read_experimental
from .figures import plot_lines, plot_net
from .html import rare_rows, write_report
from .laminate import write_laminate_report
from .sensitivity_figures import plot_sensitivity_bars, plot_sensitivity_map, plot_sensitivity_vs_force

__all__ = [
    "plot_net", "plot_lines", "plot_mean_map", "plot_sd_map", "plot_wrinkle_map", "plot_line_statistics",
    "plot_histograms", "plot_convergence", "plot_sweep", "plot_scalar_vs_factor", "plot_sensitivity_bars",
    "plot_sensitivity_vs_force", "plot_sensitivity_map", "write_report", "rare_rows", "read_experimental",
    "ExperimentalPoints", "write_design_report", "write_laminate_report",
]
