"""Both yarn directions of each FE element in the element's own reference frame.

The element frame (what LS-DYNA's shell BETA with AOPT = 0 and a Nastran material
system are measured in): e3 the element normal by its node order (right hand:
(p2 - p1) x (p3 - p1) for a triangle, the cross product of the diagonals
(p3 - p1) x (p4 - p2) for a quad), e1 the first edge p1 -> p2 made orthogonal to e3,
e2 = e3 x e1. The yarn directions mapped from the net lie on the mould's tangent plane
at the element's foot point; they are turned onto the element plane by the smallest
rotation taking the mould normal onto +-e3 (whichever is nearer), which keeps their
angle, 90 deg - shear, exactly. Yarn angles theta1, theta2 (deg) are measured from e1
about e3, in (-180, 180].

The thinning estimate is the area ratio cos(shear): a cell of an inextensible fabric
sheared by gamma covers cos(gamma) of its flat area, so its areal mass and, at constant
fibre volume fraction, its thickness grow by 1 / cos(gamma).

An element off the net gets the default theta1 = 0 (yarn 1 along e1), theta2 = 90,
shear 0 and area ratio 1, and is listed as unmapped by every flavour.
"""

from __future__ import annotations

import warnings

import numpy as np

from .directions import dot, unit

#: Default yarn angles (deg, element frame) of an element not on the net.
DEFAULT_THETA = (0.0, 90.0)
#: Quantiles of the yarn angles written for an ensemble.
ANGLE_QUANTILES = (0.05, 0.5, 0.95)


def corner_nodes(blocks) -> np.ndarray:
    """Corner node indices (M, 4) of the surface cell ``blocks``; -1 in the fourth column of
    a triangle (higher-order cells keep their corners)."""
    rows = []
    for b in blocks:
        k = 3 if b.type.startswith("triangle") else 4
        c = np.full((len(b.data), 4), -1, dtype=np.int64)
        c[:, :k] = b.data[:, :k]
        rows.append(c)
    return np.concatenate(rows)


def element_frames(points: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(e1, e2, e3) (M, 3) each: the element frames of the module doc."""
    p = points[np.where(corners < 0, corners[:, [2]], corners)]  # a triangle's 4th corner = its 3rd
    tri = corners[:, 3] < 0
    normal = np.where(tri[:, None], np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                      np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1]))
    e3 = unit(normal)
    edge = p[:, 1] - p[:, 0]
    e1 = unit(edge - dot(edge, e3)[:, None] * e3)
    return e1, np.cross(e3, e1), e3


def onto_element(v: np.ndarray, normal: np.ndarray, e3: np.ndarray) -> np.ndarray:
    """Vectors ``v`` (M, 3) turned by the smallest rotation taking the unit ``normal`` onto
    the nearer of +-``e3`` (Rodrigues' formula)."""
    target = np.where((dot(normal, e3) < 0)[:, None], -e3, e3)
    axis = np.cross(normal, target)
    c = dot(normal, target)[:, None]
    return v * c + np.cross(axis, v) + axis * dot(axis, v)[:, None] / (1.0 + c)


def yarn_angles(d1: np.ndarray, d2: np.ndarray, normal: np.ndarray, frame) -> dict:
    """Element-plane yarn vectors ``yarn1``, ``yarn2`` (M, 3) and their angles ``theta1``,
    ``theta2`` (deg) in the element ``frame`` of the mould-tangent directions ``d1``, ``d2``
    with mould normals ``normal``; NaN where the directions are."""
    e1, e2, e3 = frame
    with np.errstate(invalid="ignore"):
        y1, y2 = onto_element(d1, normal, e3), onto_element(d2, normal, e3)
    return {"yarn1": y1, "yarn2": y2,
            "theta1": np.degrees(np.arctan2(dot(y1, e2), dot(y1, e1))),
            "theta2": np.degrees(np.arctan2(dot(y2, e2), dot(y2, e1)))}


def axial_quantiles(samples: np.ndarray, about: np.ndarray, quantiles=ANGLE_QUANTILES) -> np.ndarray:
    """``quantiles`` (Q, M) deg over the realisations (axis 0, NaN skipped) of yarn angles
    ``samples`` (R, M): a yarn is a line, so each sample is first taken within +-90 deg of
    the nominal angle ``about`` (M,)."""
    dev = (samples - about + 90.0) % 180.0 - 90.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an element no realisation places: all NaN
        q = np.nanquantile(dev, quantiles, axis=0)
    return q + about


def axial_mean(samples: np.ndarray) -> np.ndarray:
    """Mean direction (M,) deg over axis 0 (NaN skipped) of the lines at angles ``samples``
    (R, M) deg: half the angle of the mean of the doubled angles."""
    doubled = np.radians(2.0 * samples)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an element no realisation places: all NaN
        return 0.5 * np.degrees(np.arctan2(np.nanmean(np.sin(doubled), axis=0), np.nanmean(np.cos(doubled), axis=0)))


def with_defaults(values: dict, frame, on_net: np.ndarray) -> dict:
    """``values`` with the default of the module doc at the elements not ``on_net``."""
    e1, e2, _ = frame
    out = dict(values)
    off = ~on_net
    out["yarn1"] = np.where(off[:, None], e1, values["yarn1"])
    out["yarn2"] = np.where(off[:, None], e2, values["yarn2"])
    for name, default in (("theta1", DEFAULT_THETA[0]), ("theta2", DEFAULT_THETA[1]), ("shear", 0.0),
                          ("area_ratio", 1.0)):
        out[name] = np.where(off, default, values[name])
    for name in [k for k in values if k.startswith(("theta1_q", "theta2_q"))]:
        out[name] = np.where(off, DEFAULT_THETA[int(name[5]) - 1], values[name])
    return out
