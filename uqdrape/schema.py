"""Names shared by every stage: ensemble dimensions and variables, quadrant labels, the
dims of a net site, the solver's modes and scalar inputs, the per-drape quantities of
interest, and the ensemble layout of a drape Dataset.

Everything that reads or writes a drape or ensemble Dataset takes its names from here, so
that a dimension, a quadrant or an input is spelt once. The module imports nothing of
uqdrape: it sits below the solver and the study file. The names here are the solver's
and the analysis's own; where a study file sets each of them is the study spec's
business (``uqdrape.study.spec``).

The force has two names, one per meaning. ``blankholder_force`` (:data:`FORCE`) is the
study's set force level (N), always a dimension of an ensemble (as the ensemble engine
writes it, ``open_ensemble`` opens it and stats and report read it; dims
(``blankholder_force``, ``realization``, ...), of length 1 unless the study sweeps the
force) and the solver's input argument. ``applied_blankholder_force``
(:data:`APPLIED_FORCE`; N) is the force a drape was run with, a per-realisation variable
of every drape Dataset the solver makes and of every ensemble: the level itself, or the
sampled value when the force is an ``[uncertainty]`` factor (the level is then the
study's fixed setting, the nominal force). :func:`at_level` and :func:`by_force` put a
drape Dataset in the ensemble layout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # annotations only: xarray is imported where a Dataset is made or read
    import xarray as xr

#: Ensemble dimensions: realisations, and the blank-holder force level (N; length 1 without a sweep).
REALIZATION = "realization"
FORCE = "blankholder_force"
#: The per-realisation force (N) each drape was run with (see the module docstring).
APPLIED_FORCE = "applied_blankholder_force"
#: A laminate's plies: the dimension ``ply`` (after the force level, before ``realization``;
#: coordinate: the ply names in stacking order, the first on the tool) and its coordinate
#: ``ply_angle``, each ply's nominal fibre-1 angle (deg) from the rosette's 0 deg direction,
#: which lies at the plan angle ``rosette_deg`` (a Dataset attribute, deg from +x).
PLY = "ply"
PLY_ANGLE = "ply_angle"
#: Prefix of a per-ply coordinate holding a drape attribute that differs between plies.
PLY_ATTR = "ply_"

#: The design record's draw-in statistic (mm): the 95 % quantile of the largest draw-in.
DRAW_IN = "q95_max_draw_in"

#: Net quadrants by the signs of (i, j). On a dome draped from its pole the quadrants with
#: i*j > 0 shear positively ("+ quadrants"), the others negatively.
QUADRANTS = ("++", "-+", "--", "+-")
PLUS_QUADRANTS = ("++", "--")
MINUS_QUADRANTS = ("-+", "+-")


def site_dims(da: xr.DataArray) -> tuple[str, str]:
    """The dims naming one site of the net: ("i", "j") for a node variable, ("cell_i",
    "cell_j") for a cell variable; ValueError for any other."""
    for dims in (("i", "j"), ("cell_i", "cell_j")):
        if set(dims) <= set(da.dims):
            return dims
    raise ValueError(f"variable {da.name!r} has dims {da.dims}; expected a node (i, j) or cell "
                     "(cell_i, cell_j) variable")


@dataclass(frozen=True)
class SolverInput:
    """A scalar input of ``uqdrape.drape.drape`` that a study fixes or samples per realisation.

    ``name`` is the drape argument and the ``[uncertainty.<name>]`` factor, ``variable``
    its per-realisation variable in a drape or ensemble Dataset; ``lower``/``upper`` its physical
    range, exclusive where ``open_range`` (a value at an open end would make the net
    degenerate).
    """

    name: str
    units: str
    long_name: str
    lower: float = -math.inf
    upper: float = math.inf
    open_range: bool = False

    @property
    def variable(self) -> str:
        """The input's per-realisation variable: its name, but :data:`APPLIED_FORCE` for the force."""
        return APPLIED_FORCE if self.name == FORCE else self.name

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
    SolverInput("blankholder_force", "N", "total blank-holder force", 0.0, 1e6),
    SolverInput("friction", "1", "fabric/blank-holder friction coefficient", 0.0, 2.0),
    SolverInput("orientation", "degree", "fibre-1 plan angle from the x axis", -360.0, 360.0),
    SolverInput("crossover_x", "mm", "crossover x"),
    SolverInput("crossover_y", "mm", "crossover y"),
    SolverInput("pre_shear", "degree", "shear of the flat blank", -90.0, 90.0, True),
    SolverInput("skew", "degree", "generator-path skew at the crossover", -90.0, 90.0, True),
)}

#: The largest net the solver is meant for: rings n, (2n + 1)^2 nodes (1000: 4 M nodes,
#: about 2.4 GB of working arrays for one energy drape). What fits this machine's memory
#: is checked before a run (``uqdrape.workflow.preflight``).
MAX_RINGS = 1000
#: Fibre spacing of a net (mm), [low, high): below 10 µm a net is no textile and its edge
#: lengths drown in the rounding of mm-sized moulds; 1 m cells no mould has.
SPACING_RANGE_MM = (0.01, 1000.0)
#: Largest tolerance of the energy minimiser on turn angles (deg): past 1 deg its "minimum"
#: is any turn at all.
MAX_TOLERANCE_DEG = 1.0

#: Drape modes: geodesic generator arms, or arms steered to minimise the forming energy.
MODES = ("geodesic", "energy")
#: Blank-holder friction models: what the friction work of a held boundary segment acts
#: on (``uqdrape.drape.energy.BlankHolder``).
BLANKHOLDER_MODELS = ("slip", "radial")

#: Per-drape quantities of interest -> their CF attributes (units, long_name); computed by
#: ``uqdrape.stats.qoi`` (the registry), ranked by sensitivity studies, summarised by
#: designs and reports.
QOI_ATTRS = {name: {"units": units, "long_name": long_name} for name, units, long_name in (
    ("max_abs_shear", "degree", "largest absolute node shear"),
    ("mean_shear_positive", "degree", "mean shear along the max-shear lines of the i*j > 0 quadrants"),
    ("mean_shear_negative", "degree", "mean shear along the max-shear lines of the i*j < 0 quadrants"),
    ("asymmetry", "degree", "mean_shear_positive + mean_shear_negative (0 when mirrored)"),
    ("blankholder_energy", "J", "blank-holder friction energy"),
    ("locked_fraction", "1", "fraction of the valid cells that are locked"),
    ("any_locked", "1", "1 if any node of the net is locked, else 0"),
    ("max_draw_in", "mm", "largest radial draw-in of the held edge"),
    ("lock_margin", "1", "largest cell shear from its zero-energy angle over its branch's locking angle "
                         "(above 1: a cell is locked)"),
)}
#: The quantities a sensitivity study ranks unless its [sensitivity] qoi says otherwise.
SENSITIVITY_QOIS = ("max_abs_shear", "mean_shear_positive", "mean_shear_negative", "asymmetry",
                    "blankholder_energy", "locked_fraction")


def at_level(ds: xr.Dataset, force: float) -> xr.Dataset:
    """Drape Dataset ``ds`` as force level ``force`` (N) of an ensemble: every variable
    given the leading length-1 dimension ``blankholder_force``."""
    out = ds.expand_dims({FORCE: [float(force)]})
    out[FORCE].attrs.update(units="N", long_name="blank-holder force level")
    return out


def ply_dataset(ds: xr.Dataset, ply) -> xr.Dataset:
    """Ply ``ply`` (a name) of a laminate ensemble as a single-ply ensemble: the ply
    selected, its per-ply attributes (``PLY_ATTR`` coordinates) back as attributes."""
    one = ds.sel({PLY: ply})
    own = [name for name in one.coords if name.startswith(PLY_ATTR) and name != PLY_ANGLE]
    attrs = {name.removeprefix(PLY_ATTR): one[name].values.item() for name in own}
    return one.drop_vars(own).assign_attrs(attrs)


def by_force(ds: xr.Dataset) -> xr.Dataset:
    """``ds`` in the ensemble layout: an ensemble as it is; a drape Dataset split by its
    distinct forces into levels (one drape per level for a batch of forces, as
    ``drape(blankholder_force=[0, 126, ...])`` gives), the realisations of each level
    renumbered 0..n-1. ValueError if the levels have different numbers of drapes."""
    import xarray as xr

    if FORCE in ds.dims:
        return ds
    forces = ds[APPLIED_FORCE].values
    parts = [ds.isel({REALIZATION: np.flatnonzero(forces == f)}) for f in np.unique(forces)]
    sizes = sorted({p.sizes[REALIZATION] for p in parts})
    if len(sizes) > 1:
        raise ValueError(f"the drapes have blank-holder forces {np.unique(forces).tolist()} N in different numbers "
                         f"({sizes} drapes per force); select drapes of one force first")
    return xr.concat([at_level(p.assign_coords({REALIZATION: np.arange(sizes[0])}), p[APPLIED_FORCE].values[0])
                      for p in parts], dim=FORCE)
