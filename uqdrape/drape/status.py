"""Per-node status codes: failure is data, not an exception."""

from enum import IntEnum

import numpy as np


class Status(IntEnum):
    """Why a node is (in)valid. Stored as int8 in the ``status`` variable."""

    OK = 0
    #: a neighbour the node is built from is invalid
    DEPENDENT = 1
    #: the circle (two spheres, or the arm step) does not meet the surface on the net's own
    #: sheet (a crossing into the mould from inside, the far side of a fold, is no root)
    NO_INTERSECTION = 2
    #: the node falls outside the mould's domain
    OFF_MOULD = 3
    #: the node's cell turns over (its +i/+j corner orientation flips)
    FOLDED = 4
    #: the node lies outside its ply's trim boundary (a laminate's ply cut to its edge)
    TRIMMED = 5

    @classmethod
    def describe(cls) -> str:
        return ", ".join(f"{s.value}={s.name.lower()}" for s in cls)


def placement_failures(status) -> tuple[float, str]:
    """The fraction of nodes of a net (status array, crossover at its centre) that could
    not be placed, and a sentence with their status counts and the likely cause."""
    status = np.asarray(status)
    failed = float((status != Status.OK).mean())
    counts = ", ".join(f"{s.name.lower()} {int((status == s).sum())}" for s in Status if (status == s).any())
    if status.flat[status.size // 2] != Status.OK:
        cause = "the crossover is off the mould"
    elif (status == Status.OFF_MOULD).any():
        cause = "the net (2 x rings x spacing) reaches past the mould's edge"
    else:
        cause = "the fabric cannot follow the mould (no intersection or folded cells)"
    return failed, f"node status: {counts}; likely {cause}"


def unplaced_error(status, budget: float, budget_name: str, net: str) -> str | None:
    """Why a drape (status array of the net named ``net``) is refused: more than ``budget``
    (the fraction named ``budget_name``) of its nodes could not be placed, so its results
    would be NaN nearly everywhere (the crossover off the mould, a net wider than the
    mould, a sheet the net cannot follow); None within the budget."""
    failed, why = placement_failures(status)
    if failed <= budget:
        return None
    return (f"{failed:.0%} of the nodes of {net} cannot be placed, more than {budget_name} = {budget:g} ({why}): "
            "use fewer rings, a smaller spacing or move the crossover")
