"""Names shared by every stage: ensemble dimensions, quadrant labels and the table of the
solver's scalar inputs.

Everything that reads or writes a drape or ensemble Dataset takes its names from here, so
that a dimension, a quadrant or an input is spelt once. The module imports nothing of
uqdrape: it sits below the solver.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Ensemble dimensions: realisations, and blank-holder force levels (N) of a sweep.
REALIZATION = "realization"
FORCE = "blankholder_force"

#: Net quadrants by the signs of (i, j). On a dome draped from its pole the quadrants with
#: i*j > 0 shear positively ("+ quadrants"), the others negatively.
QUADRANTS = ("++", "-+", "--", "+-")
PLUS_QUADRANTS = ("++", "--")
MINUS_QUADRANTS = ("-+", "+-")


@dataclass(frozen=True)
class SolverInput:
    """A scalar input of ``uqdrape.drape.drape`` that a study fixes or samples per realisation.

    ``name`` is the drape argument, the stored variable and the ``[uncertainty.<name>]``
    factor; ``section``/``key`` the study-file setting that fixes it (``index`` picks an
    element of a list setting); ``lower``/``upper`` its physical range, exclusive where
    ``open_range`` (a value at an open end would make the net degenerate).
    """

    name: str
    section: str
    key: str
    units: str
    long_name: str
    lower: float = -math.inf
    upper: float = math.inf
    open_range: bool = False
    index: int | None = None

    @property
    def setting(self) -> str:
        """The dotted study-file key of the fixed setting, e.g. ``fabric.crossover[0]``."""
        return f"{self.section}.{self.key}" + ("" if self.index is None else f"[{self.index}]")

    def admits(self, value: float) -> bool:
        """Whether ``value`` lies in the input's physical range."""
        if self.open_range:
            return self.lower < value < self.upper
        return self.lower <= value <= self.upper

    def describe_range(self) -> str:
        """The range as a sentence ending, e.g. "must be >= 0 N", "must lie in (-90, 90) degrees"."""
        unit = {"1": "", "degree": " degrees"}.get(self.units, f" {self.units}")
        if math.isinf(self.upper):
            return f"must be {'>' if self.open_range else '>='} {self.lower:g}{unit}"
        lo, hi = ("(", ")") if self.open_range else ("[", "]")
        return f"must lie in {lo}{self.lower:g}, {self.upper:g}{hi}{unit}"


#: The scalar solver inputs, in the order studies list them as factors.
SOLVER_INPUTS = {i.name: i for i in (
    # upper ends: far beyond any press (1 MN) and any fabric on steel (mu 2): a typo, not a process
    SolverInput("blankholder_force", "process", "blankholder_force_N", "N", "total blank-holder force", 0.0, 1e6),
    SolverInput("friction", "process", "friction", "1", "fabric/blank-holder friction coefficient", 0.0, 2.0),
    SolverInput("orientation", "fabric", "orientation_deg", "degree", "fibre-1 plan angle from the x axis"),
    SolverInput("crossover_x", "fabric", "crossover", "mm", "crossover x", index=0),
    SolverInput("crossover_y", "fabric", "crossover", "mm", "crossover y", index=1),
    SolverInput("pre_shear", "fabric", "pre_shear_deg", "degree", "shear of the flat blank", -90.0, 90.0, True),
    SolverInput("skew", "fabric", "skew_deg", "degree", "generator-path skew at the crossover", -90.0, 90.0, True),
)}
