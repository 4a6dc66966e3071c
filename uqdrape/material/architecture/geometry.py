"""Stitch geometry (thesis Eq 4.1-4.6, 4.24-4.26) and the fabric's area change with shear."""

from __future__ import annotations

import math

import numpy as np

from .fabric import Architecture


def stitch_segments(arch: Architecture, theta_rad):
    """(s_u, s_o (…, N), s_t) in mm at shear θ (rad): Eq 4.1, 4.2, 4.5 (constant t_t)."""
    theta = np.asarray(theta_rad, dtype=float)
    phi0 = math.radians(arch.phi0_deg)
    phi = phi0 - theta / 2.0
    c = np.cos(phi) / math.cos(phi0)
    s = np.sin(phi) / math.sin(phi0)
    n = np.asarray(arch.lapping, dtype=float)
    s_u = c * arch.stitch_length_mm
    s_o = np.sqrt((c * arch.stitch_length_mm)[..., None] ** 2 + (s[..., None] * n * arch.gauge_spacing_mm) ** 2)
    return s_u, s_o, np.full_like(theta, arch.thickness_mm)


def stitch_length(arch: Architecture, theta_rad):
    """Unit-stitch length s_L(θ) = Σ_i (2 s_u + 2 s_t + s_oi), mm (Eq 4.6)."""
    s_u, s_o, s_t = stitch_segments(arch, theta_rad)
    return arch.courses * (2.0 * s_u + 2.0 * s_t) + s_o.sum(axis=-1)


def stitch_strain(arch: Architecture, theta_rad):
    """Thread strain (s_L(θ) − s_free)/s_free, s_free = s_L(0)/(1 + ε0) (Eq 4.9, 4.22);
    negative values mean a slack thread."""
    free = stitch_length(arch, 0.0) / (1.0 + arch.prestrain)
    return stitch_length(arch, theta_rad) / free - 1.0


def pass_through_lengths(arch: Architecture, theta_rad):
    """Path lengths L_{1→ip} (…, N, 3) from the underlap apex to each pass-through point (Eq 4.24-4.26), mm."""
    s_u, s_o, s_t = stitch_segments(arch, theta_rad)
    course = 2.0 * s_u[..., None] + 2.0 * s_t[..., None] + s_o
    before = np.cumsum(course, axis=-1) - course
    p1 = s_u[..., None] + before
    p2 = s_u[..., None] + 2.0 * s_t[..., None] + s_o + before
    p3 = 2.0 * s_u[..., None] + 2.0 * s_t[..., None] + s_o + before
    return np.stack([p1, p2, p3], axis=-1)


def area_ratio(arch: Architecture, theta):
    """Current/initial fabric area sin(2φ0 − θ)/sin 2φ0 (also the tow-mat width ratio)."""
    phi0 = math.radians(arch.phi0_deg)
    return np.sin(2.0 * phi0 - theta) / math.sin(2.0 * phi0)

