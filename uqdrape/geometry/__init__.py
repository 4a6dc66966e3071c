"""Moulds (mm): analytic height fields z = h(x, y) and triangle meshes of any shape, and a
registry to build them by name.

``build("hemisphere", radius=80)`` is how a study file's ``[geometry]`` table becomes a
Surface: ``kind`` picks the class from ``KINDS``, the other keys are its constructor
arguments (each class documents its parameters and defaults).
"""

from __future__ import annotations

import inspect

from ..errors import ParameterError
from .analytic import Cone, Cylinder, DoubleDome, Hemisphere, NoseCone, Plate, Saddle
from .base import Surface
from .mesh import MeshError, MeshSurface, export_stl

#: geometry kind (as written in a study file) -> Surface class
KINDS: dict[str, type] = {
    cls.name: cls
    for cls in (Plate, Cylinder, Hemisphere, Cone, NoseCone, DoubleDome, Saddle, MeshSurface)
}


def build(kind: str, **params) -> Surface:
    """Construct the mould ``kind`` with shape ``params`` (and ``offset_mm``: its offset
    surface, ``Surface.offset``); ValueError on a bad kind or parameter."""
    if not isinstance(kind, str) or kind not in KINDS:
        raise ValueError(f"unknown geometry kind {kind!r}; valid: {', '.join(KINDS)}")
    cls = KINDS[kind]
    sig = inspect.signature(cls.__init__)
    valid = [p for p in sig.parameters if p != "self"]
    offset = params.pop("offset_mm", None)
    unknown = [p for p in params if p not in valid]
    if unknown:
        raise ParameterError(
            unknown[0], f"unknown parameter {unknown[0]!r} for geometry {kind!r}; valid: {', '.join(valid + ['offset_mm'])}"
        )
    missing = [
        p for p in valid if sig.parameters[p].default is inspect.Parameter.empty and p not in params
    ]
    if missing:
        raise ParameterError(missing[0], f"geometry {kind!r} needs parameter {missing[0]!r}")
    surface = cls(**params)
    return surface if offset is None else surface.offset(offset)


__all__ = [
    "Surface",
    "Plate",
    "Cylinder",
    "Hemisphere",
    "Cone",
    "NoseCone",
    "DoubleDome",
    "Saddle",
    "MeshSurface",
    "MeshError",
    "export_stl",
    "KINDS",
    "build",
]
