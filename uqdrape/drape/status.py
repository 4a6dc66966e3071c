"""Per-node status codes: failure is data, not an exception."""

from enum import IntEnum


class Status(IntEnum):
    """Why a node is (in)valid. Stored as int8 in the ``status`` variable."""

    OK = 0
    #: a neighbour the node is built from is invalid
    DEPENDENT = 1
    #: the circle (two spheres, or the arm step) does not meet the surface
    NO_INTERSECTION = 2
    #: the node falls outside the mould's domain
    OFF_MOULD = 3
    #: the node's cell turns over (its +i/+j corner orientation flips)
    FOLDED = 4

    @classmethod
    def describe(cls) -> str:
        return ", ".join(f"{s.value}={s.name.lower()}" for s in cls)
