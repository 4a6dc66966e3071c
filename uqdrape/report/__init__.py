"""uqdrape.report: matplotlib figures (PNG, Agg backend) and an HTML page per study."""

from .experimental import ExperimentalPoints, read_experimental
from .figures import plot_lines, plot_net

__all__ = ["plot_net", "plot_lines", "read_experimental", "ExperimentalPoints"]
