"""Fibre directions at the nodes of a draped net, tangent to the mould.

At node (i, j) the +i and +j fibre tangents are estimated by central differences of the
neighbouring nodes, (P[i+1] - P[i-1]) / 2 (second order in the spacing s on a smooth
net), one-sided (first order) where a neighbour is missing (the net's boundary, invalid
nodes), and projected onto the mould's tangent plane. Their bisector fixes the frame;
the opening angle between the two directions is set to 90 deg - the node shear, so the
exported directions carry exactly the shear the solver reports (mean of the adjacent
cells' shears), and are unit and tangent to the mould to rounding.
"""

from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot product over the last axis of batched 3-vectors."""
    return np.einsum("...k,...k->...", a, b)


def unit(a: np.ndarray) -> np.ndarray:
    """Batched 3-vectors scaled to length 1 (NaN stays NaN)."""
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def _tangent(P: np.ndarray, axis: int) -> np.ndarray:
    """Central difference of P (N, N, 3) along ``axis``, one-sided where a neighbour is NaN."""
    fwd = np.full_like(P, np.nan)
    bwd = np.full_like(P, np.nan)
    lo = [slice(None)] * 2 + [slice(None)]
    hi = list(lo)
    lo[axis], hi[axis] = slice(None, -1), slice(1, None)
    diff = P[tuple(hi)] - P[tuple(lo)]  # P[k+1] - P[k]
    fwd[tuple(lo)] = diff
    bwd[tuple(hi)] = diff
    central = 0.5 * (fwd + bwd)
    return np.where(np.isnan(central), np.where(np.isnan(fwd), bwd, fwd), central)


def _in_plane(v: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Unit part of v orthogonal to the unit normal n."""
    return unit(v - dot(v, n)[..., None] * n)


def fibre_frame(t1: np.ndarray, t2: np.ndarray, normal: np.ndarray, shear_deg: np.ndarray):
    """Unit fibre directions (d1, d2) in the plane normal to ``normal`` (unit), symmetric
    about the bisector of the tangents t1, t2 and 90 - ``shear_deg`` (deg) apart."""
    a, b = _in_plane(t1, normal), _in_plane(t2, normal)
    mid = _in_plane(a + b, normal)
    side = _in_plane(a - b, normal)
    side = unit(side - dot(side, mid)[..., None] * mid)
    half = 0.5 * np.deg2rad(90.0 - np.asarray(shear_deg, dtype=float))[..., None]
    return np.cos(half) * mid + np.sin(half) * side, np.cos(half) * mid - np.sin(half) * side


def fibre_directions(positions: np.ndarray, shear_deg: np.ndarray, surface):
    """Fibre-1 (+i) and fibre-2 (+j) unit directions (N, N, 3) at the nodes ``positions``
    (N, N, 3) mm of a net on ``surface``, and the mould's unit normals there; NaN where a
    node or its shear is missing."""
    normal = surface.normal_at(positions)
    with np.errstate(invalid="ignore"):
        d1, d2 = fibre_frame(_tangent(positions, 0), _tangent(positions, 1), normal, shear_deg)
    return d1, d2, normal


def reference_direction(orientation_deg: float, normal: np.ndarray) -> np.ndarray:
    """The plan direction ``orientation_deg`` laid onto the tangent plane of ``normal`` by the
    rotation taking z onto the normal (as the solver lays the flat blank at the crossover)."""
    psi = np.deg2rad(orientation_deg)
    vx, vy = np.cos(psi), np.sin(psi)
    nx, ny, nz = normal[..., 0], normal[..., 1], normal[..., 2]
    w = -(nx * vx + ny * vy)
    return np.stack([vx + nx * w / (1 + nz), vy + ny * w / (1 + nz), w], axis=-1)


def fibre_deviation(d1: np.ndarray, normal: np.ndarray, orientation_deg: float) -> np.ndarray:
    """Signed angle (deg) from the reference direction ``orientation_deg`` (plan angle of
    the nominal fibre 1, laid on the mould) to fibre 1, about the mould normal."""
    ref = reference_direction(orientation_deg, normal)
    return np.rad2deg(np.arctan2(dot(np.cross(ref, d1), normal), dot(ref, d1)))
