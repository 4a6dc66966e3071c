"""Shear-energy material model: normalised shear force curves -> energy per area and per cell.

Interface units: angles in degrees, N_s in N/m, segment lengths in mm, energies in J.
The evaluation methods (`energy_density`, `cell_energy`, ...) take radians because the
drape solver calls them from inside its batched kernels.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .._jit import jit

#: Points of the fine grid on which W is tabulated once per branch.
TABLE_POINTS = 4097

#: Curvature of the locked extension of W, per radian, times the largest N_s of the
#: material (N/m): k = LOCK_STIFFNESS_PER_RAD * max N_s  (J/m²/rad²). With 1e3, one
#: degree past locking adds 0.15 * max N_s J/m² and the slope grows by 17 * max N_s per
#: degree, so the minimiser treats the locking angle as a wall, yet W stays C1 for Newton.
LOCK_STIFFNESS_PER_RAD = 1.0e3

#: Default bending stiffness B (N·m²) of the generator-path penalty U_b = Σ (B/s)·δ²
#: (s in m, δ in rad). See `Material` for why 1e-6.
DEFAULT_BENDING_STIFFNESS = 1.0e-6


#: Largest normalised shear force a curve may give (N/m): a thousand times the 1000 N/m at
#: which uqdrape's cards lock; beyond it a card is a unit mistake, and its energy integral
#: and interpolants overflow.
MAX_NS = 1e6


class MaterialError(ValueError):
    """A bad material property; ``key`` names it as a card does (``shear.positive`` for a curve)."""

    def __init__(self, key: str, message: str):
        super().__init__(message)
        self.key = key


class _Pchip:
    """scipy's ``PchipInterpolator(x, y, extrapolate=False)`` of 1-D data, bitwise: its
    derivatives (Fritsch-Carlson weighted harmonic means, Moler's one-sided ends), its
    cubic pieces and its evaluation, in numpy. A card is tabulated with it when it is read
    (every energy drape, ``uqdrape validate`` included), which then imports none of
    scipy.interpolate (0.3-0.4 s); ``tests/test_material.py`` holds the two equal."""

    def __init__(self, x, y):
        self.x = x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        h = x[1:] - x[:-1]
        m = (y[1:] - y[:-1]) / h
        if y.size == 2:
            d = np.array([m[0], m[0]])
        else:
            sign = np.sign(m)
            flat = (sign[1:] != sign[:-1]) | (m[1:] == 0) | (m[:-1] == 0)
            w1, w2 = 2 * h[1:] + h[:-1], h[1:] + 2 * h[:-1]
            with np.errstate(divide="ignore", invalid="ignore"):
                mean = (w1 / m[:-1] + w2 / m[1:]) / (w1 + w2)
            d = np.zeros_like(y)
            d[1:-1][~flat] = 1.0 / mean[~flat]
            d[0] = self._end(h[0], h[1], m[0], m[1])
            d[-1] = self._end(h[-1], h[-2], m[-1], m[-2])
        # CubicHermiteSpline's pieces: c[0] s^3 + c[1] s^2 + c[2] s + c[3], s = x - x[i]
        t = (d[:-1] + d[1:] - 2 * m) / h
        self.c = np.stack((t / h, (m - d[:-1]) / h - t, d[:-1], y[:-1]))

    @staticmethod
    def _end(h0, h1, m0, m1) -> float:
        """The one-sided three-point derivative at an end, kept shape-preserving."""
        d = ((2 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
        if np.sign(d) != np.sign(m0):
            return 0.0
        if np.sign(m0) != np.sign(m1) and abs(d) > 3.0 * abs(m0):
            return 3.0 * m0
        return d

    def __call__(self, xi):
        """Values at ``xi`` (any shape), NaN outside [x[0], x[-1]] (PPoly's sums in its order)."""
        xi = np.asarray(xi, dtype=float)
        x, c = self.x, self.c
        k = np.clip(np.searchsorted(x, xi, side="right") - 1, 0, x.size - 2)
        with np.errstate(invalid="ignore", over="ignore"):  # outside the data: NaN below
            s = xi - x[k]
            s2 = s * s
            out = 0.0 + c[3, k]
            out = out + c[2, k] * s
            out = out + c[1, k] * s2
            out = out + c[0, k] * (s2 * s)
        return np.where((x[0] <= xi) & (xi <= x[-1]), out, np.nan)


def _cumulative_simpson(y, x):
    """scipy's ``cumulative_simpson(y, x=x, initial=0.0)`` of 1-D data (3 points or more),
    bitwise: each interval's Simpson integral from the quadratic through it and its right
    neighbour (its left one for the last), summed in order."""
    def pieces(y, dx):  # eq. (8) of Cartwright (2017), as scipy writes it
        x21, x32 = dx[:-1], dx[1:]
        x21_x31 = x21 / (x21 + x32)
        x21x21_x31x32 = x21_x31 * (x21 / x32)
        coeff1, coeff2, coeff3 = 3 - x21_x31, 3 + x21x21_x31x32 + x21_x31, -x21x21_x31x32
        return x21 / 6 * (coeff1 * y[:-2] + coeff2 * y[1:-1] + coeff3 * y[2:])

    dx = np.diff(x)
    ahead, behind = pieces(y, dx), pieces(y[::-1], dx[::-1])[::-1]
    integrals = np.empty(y.size - 1)
    integrals[:-1:2] = ahead[::2]
    integrals[1::2] = behind[::2]
    integrals[-1] = behind[-1]
    return np.concatenate(([0.0], np.cumsum(integrals) + 0.0))


class _Branch:
    """One shear branch (positive or negative) on the magnitude axis x = |γ| >= 0 (rad).

    `sense` is +1 for positive shear (the inter-tow angle 2φ0 closes to 2φ0 - x) and -1
    for negative shear (it opens to 2φ0 + x); the work weight is sin(2φ0 - sense·x)/sin 2φ0.
    """

    def __init__(self, angles_rad, ns, limit_rad, phi0_rad, sense, lock_stiffness):
        self.angles_rad = angles_rad
        self.ns = ns
        self.limit = limit_rad
        self.lock_stiffness = lock_stiffness
        self.force = _Pchip(angles_rad, ns)
        grid = np.linspace(0.0, limit_rad, TABLE_POINTS)
        dw = self.force(grid) * np.sin(2.0 * phi0_rad - sense * grid) / np.sin(2.0 * phi0_rad)
        w = _cumulative_simpson(dw, grid)
        self.grid, self.dw = grid, dw
        self.w_limit = float(w[-1])
        self.slope_limit = float(dw[-1])
        # the same cubic Hermite pieces, for a lookup without a search on the uniform grid
        self.step = grid[1] - grid[0]
        self.w, self.dw_step = w, dw * self.step

    @functools.cached_property
    def table(self):
        """W as scipy's cubic Hermite spline (for dW/dx), built on first use."""
        from scipy.interpolate import CubicHermiteSpline

        return CubicHermiteSpline(self.grid, self.w, self.dw, extrapolate=False)

    def denergy(self, x):
        """dW/dx (J/m²/rad) along the branch at magnitude x (rad)."""
        over = np.maximum(x - self.limit, 0.0)
        inside = self.table(np.minimum(x, self.limit), 1)
        return np.where(x > self.limit, self.slope_limit + self.lock_stiffness * over, inside)


@jit
def _branch_energy(w, dw_step, step, limit, slope_limit, lock_stiffness, x):
    """W along one branch (J/m²) at magnitude x >= 0 (rad): the Hermite piece floor(x / step)
    of the uniform table up to the limit, a quadratic wall beyond it."""
    over = max(x - limit, 0.0)
    pos = min(x, limit) / step
    k = min(max(int(pos), 0), w.size - 2)
    t = pos - k
    t2 = t * t
    t3 = t2 * t
    inside = ((2 * t3 - 3 * t2 + 1) * w[k] + (t3 - 2 * t2 + t) * dw_step[k]
              + (3 * t2 - 2 * t3) * w[k + 1] + (t3 - t2) * dw_step[k + 1])
    return inside + over * (slope_limit + 0.5 * lock_stiffness * over)


@jit
def energy_density(mat, g):
    """W(γ) (J/m²) of material kernel ``mat`` (``Material.kernel``) at γ (rad); NaN -> NaN."""
    if math.isnan(g):
        return math.nan
    w_pos, d_pos, w_neg, d_neg, c = mat
    return (_branch_energy(w_pos, d_pos, c[0], c[1], c[2], c[6], max(g, 0.0))
            + _branch_energy(w_neg, d_neg, c[3], c[4], c[5], c[6], max(-g, 0.0)))


@jit
def cell_energy(mat, gamma, s1, s2, gamma0):
    """Shear energy (J) of one cell: A0 W(γ - γ0), A0 = s1 s2 sin 2φ0 (s in mm, angles rad)."""
    return s1 * s2 * mat[4][7] * 1e-6 * energy_density(mat, gamma - gamma0)


@jit
def _density_many(mat, g, out):
    for m in range(g.size):
        out[m] = energy_density(mat, g[m])


@jit
def _cell_energy_many(mat, gamma, s1, s2, gamma0, out):
    for m in range(gamma.size):
        out[m] = cell_energy(mat, gamma[m], s1[m], s2[m], gamma0[m])


def _as_curve(branch, angles_deg, ns):
    """Validate one branch's (angle [deg], N_s [N/m]) points; return float arrays."""
    label = f"{branch} shear curve"

    def bad(text):
        raise MaterialError(f"shear.{branch}", f"{label}: {text}")

    try:
        a = np.asarray(angles_deg, dtype=float)
        n = np.asarray(ns, dtype=float)
    except (TypeError, ValueError) as exc:
        bad(f"angles and N_s must be numbers ({exc})")
    if a.ndim != 1 or n.ndim != 1 or a.size != n.size:
        bad(f"angles and N_s must be 1-D and of equal length, got shapes {a.shape} and {n.shape}")
    if a.size < 2:
        bad(f"need at least 2 points, got {a.size}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(n))):
        bad("angles and N_s must be finite numbers")
    if a[0] != 0.0:
        bad(f"the first angle must be 0 deg (W is integrated from 0), got {a[0]:g}")
    steps = np.diff(a)
    if np.any(steps <= 0.0):
        k = int(np.argmax(steps <= 0.0))
        bad(f"angles must be strictly increasing, got {a[k]:g} then {a[k + 1]:g} deg")
    if np.any(n < 0.0):
        k = int(np.argmax(n < 0.0))
        bad(f"N_s must be >= 0 (give the magnitude for the negative branch), got {n[k]:g} N/m at {a[k]:g} deg")
    if np.any(n > MAX_NS):
        k = int(np.argmax(n > MAX_NS))
        bad(f"N_s must be at most {MAX_NS:g} N/m (a fabric locks near 1000 N/m), got {n[k]:g} N/m at {a[k]:g} deg")
    return a, n


class Material:
    """A textile's in-plane shear behaviour as used by the pin-jointed-net drape.

    Built from normalised shear force curves N_s(γ) (N/m, picture-frame normalisation,
    thesis §3.3.2) for positive shear (fabric extended along the stitch: the stiff side
    of a tricot NCF) and negative shear (given as magnitudes at positive angles); a woven
    fabric gives one curve, used for both. The energy per unit initial area is

        W(γ) = ∫_0^γ N_s(t) · sin(2φ0 − t) / sin(2φ0) dt      (J/m², t in rad),

    integrated from 0 along each branch, so W(0) = 0, W >= 0 and W is monotone in |γ| on
    each side. N_s is interpolated by a monotone cubic (PCHIP, no overshoot, so it stays
    >= 0), W is tabulated once on a fine grid (Simpson) and evaluated by a cubic Hermite
    spline whose slopes are the exact dW/dγ, so W is C1 within a branch.

    N_s must be >= 0 (a card read from a file also somewhere > 0 on each branch:
    ``cards.load_material``; a scattered realisation's curve may clip to 0); it may fall with γ (an NCF's stitch
    can soften: the EBXhd-936 card derived from its architecture peaks at 12°), since W
    stays monotone in |γ| whatever the shape of a non-negative N_s.

    Locking: beyond the locking angle of a branch, W continues as a quadratic wall
    W(γ_L) + W'(γ_L)·Δ + ½·k·Δ², k = LOCK_STIFFNESS_PER_RAD · max N_s (C1 at γ_L), and
    `is_locked` flags it. The locking angle of a branch defaults to the last angle of its
    curve and may not exceed it (there is no data to integrate beyond it).

    Bending: `bending_stiffness` B (N·m²) feeds the solver's generator-path penalty
    U_b = Σ (B/s)·δ² (s in m, δ the in-plane turning angle in rad). The thesis uses it only
    to stop arms folding back, so it must be small next to shear. Default 1e-6 N·m²: for
    s = 5 mm and δ = 1° it gives U_b = 1e-6/0.005·(0.01745)² = 6.1e-8 J, while one 5 × 5 mm
    cell sheared 5° stores 9.6e-7 J on the softest shipped branch (FGE 106hd-like, negative
    shear) and 3.2e-6 J in the generic woven: 6 % and 2 % of a single cell, and far less
    than the ~2k cells a quadrant adds at ring k.

    Sign: γ > 0 closes the angle between +fibre1 and +fibre2 (model.md §1).
    `stitch_direction_deg` (NCFs only) is the stitch direction measured in the flat,
    unsheared fabric from fibre 1 towards fibre 2; the convention that positive shear
    extends the stitch requires it to bisect +fibre1 and +fibre2, i.e. to equal φ0
    (mod 180°). A stitch along the other bisector means the branches are swapped.

    Parameters (interface units): name, angles_deg_pos [deg], ns_pos [N/m],
    angles_deg_neg [deg, magnitudes], ns_neg [N/m, magnitudes] (None: same as positive),
    phi0_deg [deg] (half the initial inter-tow angle, 45 for orthogonal fabrics),
    locking_angle_deg [deg] (positive branch; None: end of the positive curve),
    locking_angle_neg_deg [deg, magnitude] (None: locking_angle_deg if that is given,
    else the end of the negative curve),
    bending_stiffness [N·m²], stitch_direction_deg [deg] or None, description, note,
    architecture (a derived card's [architecture] record, dict, or None).
    """

    def __init__(self, name, angles_deg_pos, ns_pos, angles_deg_neg=None, ns_neg=None, *, phi0_deg=45.0,
                 locking_angle_deg=None, locking_angle_neg_deg=None, bending_stiffness=DEFAULT_BENDING_STIFFNESS,
                 stitch_direction_deg=None, description="", note="", architecture=None):
        if not isinstance(name, str) or not name:
            raise MaterialError("name", f"name must be a non-empty string, got {name!r}")
        self.name = name
        self.description = str(description)
        self.note = str(note)
        #: the [architecture] record of a card derived by uqdrape.material.architecture (else None)
        self.architecture = architecture

        phi0_deg = float(phi0_deg)
        if not 0.0 < phi0_deg < 90.0:
            raise MaterialError("phi0_deg", f"phi0_deg must be in (0, 90) deg, got {phi0_deg:g}")
        self.phi0_deg = phi0_deg
        self.phi0_rad = np.deg2rad(phi0_deg)

        if (angles_deg_neg is None) != (ns_neg is None):
            raise MaterialError("shear.negative", "angles_deg_neg and ns_neg must be given together (or both omitted "
                                "for a symmetric fabric)")
        a_pos, n_pos = _as_curve("positive", angles_deg_pos, ns_pos)
        a_neg, n_neg = (a_pos, n_pos) if angles_deg_neg is None else _as_curve("negative", angles_deg_neg, ns_neg)
        self.symmetric = bool(a_pos.shape == a_neg.shape and np.array_equal(a_pos, a_neg)
                              and np.array_equal(n_pos, n_neg))

        lock_pos = a_pos[-1] if locking_angle_deg is None else float(locking_angle_deg)
        if locking_angle_neg_deg is not None:
            lock_neg = float(locking_angle_neg_deg)
        elif locking_angle_deg is not None:
            lock_neg = lock_pos
        else:
            lock_neg = a_neg[-1]
        # Positive shear closes the inter-tow angle to 2φ0 - γ, negative opens it to 2φ0 + |γ|:
        # both must stay inside (0, 180) deg for the work weight to be positive.
        for label, lock, data_end, geometric in (
            ("locking_angle_deg", lock_pos, a_pos[-1], 2.0 * phi0_deg),
            ("locking_angle_neg_deg", lock_neg, a_neg[-1], 180.0 - 2.0 * phi0_deg),
        ):
            if not 0.0 < lock <= data_end:
                raise MaterialError(
                    label, f"{label} must be in (0, {data_end:g}] deg (the end of that branch's curve), got {lock:g}")
            if lock >= geometric:
                raise MaterialError(label, f"{label} must be below {geometric:g} deg, where the tows of a "
                                           f"phi0 = {phi0_deg:g} deg fabric become parallel, got {lock:g}")
        self.locking_angle_deg = lock_pos
        self.locking_angle_neg_deg = lock_neg

        bending_stiffness = float(bending_stiffness)
        if not (np.isfinite(bending_stiffness) and bending_stiffness >= 0.0):
            raise MaterialError("bending_stiffness",
                                f"bending_stiffness must be a finite number >= 0 N·m², got {bending_stiffness:g}")
        self.bending_stiffness = bending_stiffness

        if stitch_direction_deg is not None:
            stitch_direction_deg = float(stitch_direction_deg)
            off = (stitch_direction_deg - phi0_deg + 90.0) % 180.0 - 90.0
            if abs(off) > 1e-9:
                raise MaterialError("stitch_direction_deg", "stitch_direction_deg must bisect +fibre1 and +fibre2, "
                                    f"i.e. equal phi0_deg = {phi0_deg:g} (mod 180), got {stitch_direction_deg:g}; for "
                                    "a stitch along the other bisector swap the positive and negative curves")
        self.stitch_direction_deg = stitch_direction_deg

        self._curves = {"positive": (a_pos, n_pos), "negative": (a_neg, n_neg)}
        stiffness = LOCK_STIFFNESS_PER_RAD * max(float(n_pos.max()), float(n_neg.max()), 1.0)
        self._pos = _Branch(np.deg2rad(a_pos), n_pos, np.deg2rad(lock_pos), self.phi0_rad, +1, stiffness)
        self._neg = _Branch(np.deg2rad(a_neg), n_neg, np.deg2rad(lock_neg), self.phi0_rad, -1, stiffness)
        p, m = self._pos, self._neg
        #: the compiled form of W: both branches' tables and [step, limit, end slope] of each,
        #: the wall stiffness and sin 2φ0 (``cell_energy``)
        self.kernel = (p.w, p.dw_step, m.w, m.dw_step,
                       np.array([p.step, p.limit, p.slope_limit, m.step, m.limit, m.slope_limit, stiffness,
                                 np.sin(2.0 * self.phi0_rad)]))

    @classmethod
    def from_curves(cls, name, angles_deg_pos, ns_pos, angles_deg_neg=None, ns_neg=None, **props):
        """Material from N_s points per branch (deg, N/m); props as in `Material`."""
        return cls(name, angles_deg_pos, ns_pos, angles_deg_neg, ns_neg, **props)

    def curve(self, branch):
        """The input points of one branch ("positive" or "negative"): (angles [deg], N_s [N/m])."""
        if branch not in ("positive", "negative"):
            raise ValueError(f"branch must be 'positive' or 'negative', got {branch!r}")
        angles, ns = self._curves[branch]
        return angles.copy(), ns.copy()

    def energy_density(self, gamma_rad):
        """W(γ) in J/m² per unit initial area; γ signed, in rad, any array shape; NaN -> NaN."""
        g = np.asarray(gamma_rad, dtype=float)
        out = np.empty(g.size)
        _density_many(self.kernel, np.ascontiguousarray(g).ravel(), out)
        return out.reshape(g.shape)

    def denergy_density(self, gamma_rad):
        """dW/dγ in J/m²/rad; at γ = 0 it returns 0 (a subgradient when N_s(0) > 0)."""
        g = np.asarray(gamma_rad, dtype=float)
        pos = self._pos.denergy(np.maximum(g, 0.0))
        neg = self._neg.denergy(np.maximum(-g, 0.0))
        return np.where(g > 0.0, pos, np.where(g < 0.0, -neg, 0.0 * g))

    def is_locked(self, gamma_rad):
        """True where γ (rad) lies beyond the locking angle of its branch; NaN -> False."""
        g = np.asarray(gamma_rad, dtype=float)
        return (g > self._pos.limit) | (-g > self._neg.limit)

    def blank_shear_error(self, shear_deg: float) -> str | None:
        """Why a flat blank pre-sheared by ``shear_deg`` (deg) cannot be draped with this
        card (the end of a sentence "the blank is ..."), or None: at or past the locking
        angle of that branch it is locked before it touches the mould. (A skew of the
        generator paths is a choice of the drape, not of the blank: the thesis's Fig 5.5
        skews past locking and the energy says so.)"""
        lock, sign = (self.locking_angle_deg, "+") if shear_deg >= 0 else (self.locking_angle_neg_deg, "-")
        if abs(shear_deg) < lock:
            return None
        return f"at or past the card {self.name}'s locking angle {sign}{lock:g} deg (locked before forming)"

    def cell_energy(self, gamma_rad, s1_mm, s2_mm, gamma0_rad=0.0):
        """Shear energy (J) of cells with fibre segments s1, s2 (mm) and zero-energy angle γ0 (rad).

        U = A0 · W(γ − γ0), A0 = s1·s2·sin 2φ0 the initial cell area (mm² -> m²: × 1e-6).
        Arguments broadcast against each other.
        """
        args = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (gamma_rad, s1_mm, s2_mm, gamma0_rad)))
        out = np.empty(args[0].size)
        _cell_energy_many(self.kernel, *(np.ascontiguousarray(a).ravel() for a in args), out)
        return out.reshape(args[0].shape)

    def shear_force(self, gamma_rad):
        """The input curve N_s(γ) in N/m, signed (negative for γ < 0); NaN outside the data."""
        g = np.asarray(gamma_rad, dtype=float)
        pos = self._pos.force(np.maximum(g, 0.0))
        neg = self._neg.force(np.maximum(-g, 0.0))
        return np.where(g >= 0.0, pos, -neg)

    def __repr__(self):
        return (f"Material({self.name!r}, phi0_deg={self.phi0_deg:g}, locking_angle_deg={self.locking_angle_deg:g}, "
                f"locking_angle_neg_deg={self.locking_angle_neg_deg:g}, bending_stiffness={self.bending_stiffness:g}, "
                f"symmetric={self.symmetric})")
