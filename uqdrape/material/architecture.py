"""Fabric architecture -> shear curve: the non-crimp-fabric model of Wiggers (2007), ch. 4.

An :class:`Architecture` (read from a TOML file by :func:`load_architecture`) describes
a stitched ±φ0 non-crimp fabric: stitch length s_l, gauge (s_g = 25.4 mm / gauge),
lapping sequence {n_i}, fabric thickness, the stitch yarn's tension-strain law and
pre-strain, the tows' compaction law and the crossover size. :func:`energy_terms`
evaluates each energy term of thesis §4.3 per unit initial fabric area (J/m²) on a θ
grid, integrated outward from θ = 0 along each branch:

- ``stitch_tension``   Eq 4.1-4.13: stitch geometry -> unit-stitch length s_L(θ) ->
  strain against the thread's free length s_L(0)/(1 + ε0) -> U = s_free ∫ S(ε) dε / A_s;
  the thread is slack (no force) below its free length and carries nothing once the
  strain has reached the failure strain (the energy stays where it was);
- ``stitch_friction``  Eq 4.24-4.33: slip of the thread through the 3 pass-through points
  of each course, U = μ_s Σ ∫ S_s de / A_s, e = |L(θ) − (1 + ε_s) L(0)| measured from the
  knitted state (trapezium rule, as the thesis);
- ``compaction``       Eq 4.35 with the Cai-Gutowski/McBride law, Eq 2.23-2.29: the tows
  (two layers of thickness t0/2, constant thickness: dry fabric) are compacted laterally
  as the fabric area falls; U = -∫ σ_b dV per unit initial area (the energy route; the
  printed Eq 4.36 is ambiguous, thesis-notes §2.5);
- ``crossover``        Eq 4.37-4.42: friction between the two tow layers over each
  crossover, path lines of the relative velocity field integrated by RK4 on a 40 × 40
  element grid, U = μ P Σ A_j l_i per crossover / crossover area, P = σ_b.

The terms are summed at the energy level and differentiated numerically (np.gradient)
to N_s = (dW/dθ) · sin 2φ0 / sin(2φ0 − θ) (Eq 4.14-4.15). :func:`derive_card` turns the
sum into a material card whose branches start at the zero-force angle γ0: the rest state
reached by walking downhill on the summed energy from the knitted state θ = 0; negative
when the pre-strained stitch pulls harder than its friction holds (thesis L9189-9195).

Not modelled: the variable-thickness balance of §4.3.3 (thickness from stitch tension =
compaction pressure × unit area / 4); every term here is at constant thickness.

Calibration (:func:`calibrate`): the thesis does not print McBride's compaction constants
or the stitch pre-strain. ``beta`` is fitted so that the negative branch (stitch slack:
compaction + crossover friction only) reaches a stated N_s at a stated angle, and the
pre-strain so that γ0 equals a stated angle; an architecture file names its targets in
``[calibration]`` or takes the fitted constants of another file (``from = "x.toml"``).

Units: lengths mm, angles deg at the interface (rad inside), forces N, N_s N/m, W J/m².
"""

from __future__ import annotations

import functools
import math
import tomllib
from importlib import resources
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.integrate import cumulative_trapezoid
from scipy.optimize import brentq

from .model import DEFAULT_BENDING_STIFFNESS

#: Version of this model, recorded in every derived card.
MODEL_VERSION = "wiggers2007-ch4/1"
#: Step of the θ grid on which the energies are summed and differentiated (deg).
GRID_STEP_DEG = 0.05
#: Half-range of the θ grid (deg): thesis Fig 4.18 plots -75..75.
GRID_LIMIT_DEG = 75.0
#: Hexagonal packing limit of aligned fibres, π/(2√3) (thesis Fig 4.4).
HEXAGONAL_VA = math.pi / (2.0 * math.sqrt(3.0))
#: Elements per side of the crossover grid (the thesis needed 40 to converge, L7335).
CROSSOVER_ELEMENTS = 40
#: Step of the crossover path-line integration (deg of fabric shear; the thesis used 0.5).
CROSSOVER_STEP_DEG = 0.5
#: Angles (deg) of the derived card's curve points: 0, 1, 2, ... up to the branch end.
CARD_STEP_DEG = 1.0
TERMS = ("stitch_tension", "stitch_friction", "compaction", "crossover")


class ArchitectureError(ValueError):
    """A bad architecture; ``key`` is the offending Architecture field (None: several)."""

    def __init__(self, message, key=None):
        super().__init__(message)
        self.key = key


@dataclass(frozen=True)
class Architecture:
    """A stitched non-crimp fabric (thesis §4.3). Lengths mm, angles deg, forces N.

    Stitch: ``stitch_length_mm`` s_l, ``gauge`` needles per inch (s_g = 25.4/gauge mm),
    ``lapping`` {n_i} (sum 0; tricot (1, -1), pillar (0, 0), (1, 0, -1, 0)),
    ``thickness_mm`` t0 (through-thickness segment s_t = t0, both tow layers; constant:
    dry fabric), ``stitch_stiffness_N`` E_s·s_A (linear) or ``tension_curve`` =
    ((strain, ...), (tension N, ...)) tabulated, ``failure_strain``, ``prestrain`` ε0
    (strain of the thread at θ = 0: s_free = s_L(0)/(1 + ε0)), ``stitch_friction`` μ_s.
    Compaction (Cai-Gutowski/McBride): ``vf0`` tow V_f at θ = 0, ``v0`` V_f at zero bulk
    stress, ``va`` packing limit, ``fibre_modulus_GPa`` E_f, ``beta`` the arch span/height
    ratio. Crossover: ``crossover_side_mm``, ``crossover_friction`` μ, ``tow_shear_ratio``
    γ_t/ω. ``calibration`` records how fitted values were obtained.
    """

    name: str
    stitch_length_mm: float
    gauge: float
    prestrain: float
    beta: float
    lapping: tuple[int, ...] = (1, -1)
    phi0_deg: float = 45.0
    thickness_mm: float = 2.0
    stitch_stiffness_N: float | None = 15.725
    tension_curve: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    failure_strain: float = 0.17
    stitch_friction: float = 0.3
    vf0: float = 0.35
    v0: float = 0.35
    va: float = HEXAGONAL_VA
    fibre_modulus_GPa: float = 72.0
    crossover_side_mm: float = 1.87
    crossover_friction: float = 0.3
    tow_shear_ratio: float = 0.3
    description: str = ""
    source: str = ""
    calibration: dict = field(default_factory=dict)

    def __post_init__(self):
        _validate(self)

    @property
    def gauge_spacing_mm(self) -> float:
        """s_g = 25.4 mm / gauge."""
        return 25.4 / self.gauge

    @property
    def courses(self) -> int:
        """N, the courses of one unit stitch (length of the lapping sequence)."""
        return len(self.lapping)

    @property
    def unit_area_mm2(self) -> float:
        """A_s = N s_l s_g (Eq 4.12), mm²."""
        return self.courses * self.stitch_length_mm * self.gauge_spacing_mm

    @property
    def locking_angle_deg(self) -> float:
        """|θ| at which the tows reach V_a at constant thickness (Eq 4.35), deg."""
        phi0 = math.radians(self.phi0_deg)
        return math.degrees(2.0 * phi0 - math.asin(math.sin(2.0 * phi0) * self.vf0 / self.va))


def _validate(a: Architecture) -> None:
    def bad(key, why):
        raise ArchitectureError(f"{key} = {getattr(a, key)!r} is invalid: {why}", key)

    for key in ("stitch_length_mm", "gauge", "thickness_mm", "crossover_side_mm", "fibre_modulus_GPa", "beta"):
        value = getattr(a, key)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            bad(key, "must be a number > 0")
    if not 0.0 < a.phi0_deg < 90.0:
        bad("phi0_deg", "must lie in (0, 90) deg")
    if (len(a.lapping) == 0 or any(not isinstance(n, int) or isinstance(n, bool) for n in a.lapping)
            or sum(a.lapping) != 0):
        bad("lapping", "must be a non-empty list of integer needle shifts summing to 0, e.g. [1, -1] (tricot)")
    if not 0.0 < a.failure_strain:
        bad("failure_strain", "must be > 0")
    if not (math.isfinite(a.prestrain) and -1.0 < a.prestrain < a.failure_strain):
        bad("prestrain", f"must lie in (-1, failure_strain = {a.failure_strain:g}): a thread past failure holds nothing")
    if (a.stitch_stiffness_N is None) == (a.tension_curve is None):
        raise ArchitectureError("give the stitch yarn law as exactly one of stitch_stiffness_N or a tension curve",
                                "stitch_stiffness_N")
    if a.stitch_stiffness_N is not None and not a.stitch_stiffness_N > 0:
        bad("stitch_stiffness_N", "must be > 0 (E_s·s_A, N)")
    if a.tension_curve is not None:
        strain, tension = (np.asarray(v, dtype=float) for v in a.tension_curve)
        if (strain.ndim != 1 or strain.size < 2 or strain.shape != tension.shape or strain[0] != 0.0
                or tension[0] != 0.0 or np.any(np.diff(strain) <= 0) or np.any(tension < 0)):
            bad("tension_curve", "needs >= 2 points, strains increasing from 0, tensions >= 0 starting at 0")
    for key in ("stitch_friction", "crossover_friction"):
        if not getattr(a, key) >= 0:
            bad(key, "must be >= 0")
    if not 0.0 <= a.tow_shear_ratio < 1.0:
        bad("tow_shear_ratio", "must lie in [0, 1): the tows shear less than the fabric")
    if not 0.0 < a.v0 <= a.vf0:
        bad("vf0", f"must be >= v0 = {a.v0:g} (McBride's minimum volume fraction) and v0 > 0")
    if not a.vf0 < a.va <= 1.0:
        bad("vf0", f"must be below va = {a.va:g}: the tows would be locked before shear")


# ----------------------------------------------------------------------------- geometry


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


def _pass_through_lengths(arch: Architecture, theta_rad):
    """Path lengths L_{1→ip} (…, N, 3) from the underlap apex to each pass-through point (Eq 4.24-4.26), mm."""
    s_u, s_o, s_t = stitch_segments(arch, theta_rad)
    course = 2.0 * s_u[..., None] + 2.0 * s_t[..., None] + s_o
    before = np.cumsum(course, axis=-1) - course
    p1 = s_u[..., None] + before
    p2 = s_u[..., None] + 2.0 * s_t[..., None] + s_o + before
    p3 = 2.0 * s_u[..., None] + 2.0 * s_t[..., None] + s_o + before
    return np.stack([p1, p2, p3], axis=-1)


# ----------------------------------------------------------------------------- energy terms


def _tension(arch: Architecture, strain):
    """Thread tension S(ε) (N), 0 when slack; and the stored energy per free length ∫_0^ε S dε (N)."""
    e = np.maximum(strain, 0.0)
    if arch.tension_curve is None:
        k = arch.stitch_stiffness_N
        return k * e, 0.5 * k * e * e
    x, t = (np.asarray(v, dtype=float) for v in arch.tension_curve)
    slope = (t[-1] - t[-2]) / (x[-1] - x[-2])
    cum = cumulative_trapezoid(t, x, initial=0.0)
    inside = np.minimum(e, x[-1])
    tension = np.interp(inside, x, t) + slope * (e - inside)
    k = np.clip(np.searchsorted(x, inside, side="right") - 1, 0, x.size - 2)
    tk = t[k] + (inside - x[k]) * (t[k + 1] - t[k]) / (x[k + 1] - x[k])
    energy = cum[k] + 0.5 * (t[k] + tk) * (inside - x[k])
    energy = energy + (e - inside) * (t[-1] + 0.5 * slope * (e - inside))
    return tension, energy


def _outward(theta):
    """Index arrays walking the grid from θ = 0 outward: (positive branch, negative branch)."""
    zero = int(np.argmin(np.abs(theta)))
    return np.arange(zero, theta.size), np.arange(zero, -1, -1)


def _branchwise(theta, fn):
    """Apply fn(indices) -> values along both branches from θ = 0 and merge."""
    out = np.empty_like(theta)
    for idx in _outward(theta):
        out[idx] = fn(idx)
    return out


def _stitch_terms(arch: Architecture, theta):
    """(W_tension, W_friction, tension S) on the grid θ (rad, containing 0): J/m², J/m², N."""
    free = stitch_length(arch, 0.0) / (1.0 + arch.prestrain)
    strain = stitch_strain(arch, theta)
    tension, stored = _tension(arch, strain)
    # failure: from the first grid point (walking out from 0) at or past the failure strain
    # the thread carries nothing and its stored energy stays where it was
    for idx in _outward(theta):
        broken = np.maximum.accumulate(strain[idx] >= arch.failure_strain)
        if broken.any():
            first = idx[int(np.argmax(broken))]
            stored[idx[broken]] = stored[first]
            tension[idx[broken]] = 0.0
    to_j_per_m2 = 1e3 / arch.unit_area_mm2  # N·mm per mm² -> J/m²
    zero = _outward(theta)[0][0]
    w_tension = (stored - stored[zero]) * free * to_j_per_m2
    # friction, Eq 4.30-4.33: slip through every pass-through point against the uniform strain
    lengths = _pass_through_lengths(arch, theta)
    geometric = stitch_length(arch, theta) / stitch_length(arch, 0.0) - 1.0
    slip = np.abs(lengths - (1.0 + geometric)[:, None, None] * lengths[zero]).sum(axis=(-1, -2))
    friction = _branchwise(theta, lambda idx: cumulative_trapezoid(tension[idx], slip[idx], initial=0.0))
    w_friction = arch.stitch_friction * friction * to_j_per_m2
    return w_tension, w_friction, tension


def _area_ratio(arch: Architecture, theta):
    """Current/initial fabric area sin(2φ0 − θ)/sin 2φ0 (also the tow-mat width ratio)."""
    phi0 = math.radians(arch.phi0_deg)
    return np.sin(2.0 * phi0 - theta) / math.sin(2.0 * phi0)


def fibre_volume_fraction(arch: Architecture, theta_rad):
    """Tow V_f(θ) at constant thickness, Eq 4.35."""
    return arch.vf0 / _area_ratio(arch, np.asarray(theta_rad, dtype=float))


def bulk_stress(arch: Architecture, vf):
    """Cai-Gutowski/McBride lateral bulk stress σ_b (Pa, compression > 0) at tow V_f, Eq 2.23-2.29.

    ε_b = sqrt(V_f/V0) − 1 (compression positive), ζ = sqrt(V_a/V_f);
    B_ll = 4ζ²[1 + 2(ζ−1)²]/(πE_f), B_bl = −16β²ζ(ζ−1)³/(π³E_f),
    B_bb = β⁴(ζ−1)⁴/(3πE_f) and σ_b = ε_b B_ll/(B_bb B_ll − B_bl²) (zero axial strain).
    B_bb is read with β⁴ where the extracted Eq 2.27 shows ζ⁴: only then is the
    determinant positive for any β (B_bl²/(B_bb B_ll) ≤ 192/π⁴·½ < 1) and Eq 2.29
    reduces to Gutowski's σ_b = (3πE_f/β⁴)(sqrt(V_f/V0) − 1)/(ζ − 1)⁴ without coupling.
    σ_b = 0 below V0, +inf at or beyond V_a.
    """
    vf = np.asarray(vf, dtype=float)
    e_f = arch.fibre_modulus_GPa * 1e9
    with np.errstate(divide="ignore", invalid="ignore"):
        zeta = np.sqrt(arch.va / vf)
        b_ll = 4.0 * zeta**2 * (1.0 + 2.0 * (zeta - 1.0) ** 2) / (math.pi * e_f)
        b_bl = -16.0 * arch.beta**2 * zeta * (zeta - 1.0) ** 3 / (math.pi**3 * e_f)
        b_bb = arch.beta**4 * (zeta - 1.0) ** 4 / (3.0 * math.pi * e_f)
        sigma = (np.sqrt(vf / arch.v0) - 1.0) * b_ll / (b_bb * b_ll - b_bl**2)
    return np.where(vf >= arch.va, np.inf, np.where(vf <= arch.v0, 0.0, sigma))


def _compaction(arch: Architecture, theta):
    """W_c(θ) = −∫ σ_b dV, V = t0 · area ratio (both tow layers, per unit initial area), J/m²."""
    sigma = bulk_stress(arch, fibre_volume_fraction(arch, theta))
    t0 = arch.thickness_mm * 1e-3
    dvol = t0 * np.gradient(_area_ratio(arch, theta), theta)  # m per rad
    return _branchwise(theta, lambda idx: cumulative_trapezoid(-sigma[idx] * dvol[idx], theta[idx], initial=0.0))


@functools.lru_cache(maxsize=64)
def _crossover_slip(a: float, tow_shear_ratio: float, phi0_deg: float, theta_end_rad: float):
    """Slip-area of one crossover: Σ_j A_j l_ij per path step (mm³) and the step ends θ (rad);
    cached, as it depends only on the crossover's geometry.

    Relative velocity of the two tow layers, Eq 4.37: v = Ω(θ)·(−Y, X) with
    Ω = (1 − γ_t/ω)(1 − sin|θ|) per unit fabric shear rate (the field is a rotation about
    the crossover centre; |θ| keeps the two shear directions alike). Path lines start at
    the centres of a 40 × 40 grid over the initial square crossover of side a and are
    integrated by RK4; a step's increment counts only if the point lies inside the
    crossover (two tow strips of width a·sin(2φ0−θ)/sin 2φ0 crossing at 2φ0 − θ) at both
    ends of the step (thesis L7335-7355).
    """
    m = CROSSOVER_ELEMENTS
    centres = (np.arange(m) + 0.5) / m * a - a / 2.0
    x, y = (v.ravel() for v in np.meshgrid(centres, centres))
    # fixed steps from 0 (the last one shorter), so that every grid shares the same path
    step = math.copysign(math.radians(CROSSOVER_STEP_DEG), theta_end_rad)
    whole = int(theta_end_rad / step + 1e-9)
    ts = step * np.arange(whole + 1)
    if abs(theta_end_rad - ts[-1]) > 1e-12:
        ts = np.append(ts, theta_end_rad)
    steps = ts.size - 1
    ratio = 1.0 - tow_shear_ratio
    phi0 = math.radians(phi0_deg)

    def rate(t, px, py):
        om = ratio * (1.0 - math.sin(abs(t))) * math.copysign(1.0, theta_end_rad)
        return -om * py, om * px

    def inside(t, px, py):
        half = 0.5 * a * math.sin(2.0 * phi0 - t) / math.sin(2.0 * phi0)
        # layer 1 along x; layer 2 along the direction at the current inter-tow angle 2φ0 − t
        alpha = 2.0 * phi0 - t
        return (np.abs(py) <= half) & (np.abs(px * math.sin(alpha) - py * math.cos(alpha)) <= half)

    area = a * a / (m * m)
    out = np.zeros(steps)
    was_in = inside(0.0, x, y)
    for k in range(steps):
        t, h = ts[k], ts[k + 1] - ts[k]
        k1 = rate(t, x, y)
        k2 = rate(t + h / 2, x + abs(h) / 2 * k1[0], y + abs(h) / 2 * k1[1])
        k3 = rate(t + h / 2, x + abs(h) / 2 * k2[0], y + abs(h) / 2 * k2[1])
        k4 = rate(t + h, x + abs(h) * k3[0], y + abs(h) * k3[1])
        nx = x + abs(h) / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        ny = y + abs(h) / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        now_in = inside(ts[k + 1], nx, ny)
        both = was_in & now_in
        out[k] = area * np.hypot(nx - x, ny - y)[both].sum()
        x, y, was_in = nx, ny, now_in
    ts.flags.writeable = out.flags.writeable = False  # shared by the cache
    return ts, out


def _crossover(arch: Architecture, theta):
    """W_X(θ) = μ Σ P·(slip area) / a² per unit initial area, P = σ_b at the step (J/m²)."""
    w = np.zeros_like(theta)
    a2 = arch.crossover_side_mm**2
    for idx in _outward(theta):
        end = theta[idx[-1]]
        if end == 0.0:
            continue
        ts, slip = _crossover_slip(arch.crossover_side_mm, arch.tow_shear_ratio, arch.phi0_deg, float(end))
        mid = 0.5 * (ts[1:] + ts[:-1])
        pressure = bulk_stress(arch, fibre_volume_fraction(arch, mid))
        cum = np.concatenate([[0.0], np.cumsum(pressure * slip)])  # Pa·mm³
        w[idx] = arch.crossover_friction * np.interp(np.abs(theta[idx]), np.abs(ts), cum) * 1e-9 / (a2 * 1e-6)
    return w


def theta_grid(limit_deg: float | None = None) -> np.ndarray:
    """The symmetric θ grid (rad), GRID_STEP_DEG apart, through 0, up to ±limit_deg."""
    limit = GRID_LIMIT_DEG if limit_deg is None else limit_deg
    n = int(round(limit / GRID_STEP_DEG))
    return np.deg2rad(np.arange(-n, n + 1) * GRID_STEP_DEG)


def energy_terms(arch: Architecture, theta_rad=None) -> dict:
    """Each term's energy per unit initial area W (J/m²) on the grid θ (rad, must hold 0).

    Returns {"theta": θ, term: W for term in TERMS}; +inf where the tows are locked.
    """
    theta = theta_grid(min(GRID_LIMIT_DEG, arch.locking_angle_deg)) if theta_rad is None else np.asarray(theta_rad)
    if not np.any(theta == 0.0):
        raise ValueError("the θ grid must contain 0 (energies are integrated outward from it)")
    w_t, w_f, _ = _stitch_terms(arch, theta)
    return {"theta": theta, "stitch_tension": w_t, "stitch_friction": w_f,
            "compaction": _compaction(arch, theta), "crossover": _crossover(arch, theta)}


def branch_forces(arch: Architecture, theta, energy):
    """N_s = (dW/dθ) sin 2φ0 / sin(2φ0 − θ) (Eq 4.14-4.15), N/m, by np.gradient within each
    branch (one-sided at θ = 0, so a term with a kink at 0, friction, keeps its jump).

    Returns ((θ ≥ 0, N_s), (θ ≤ 0, N_s)), both starting at θ = 0 and running outward.
    """
    return tuple((theta[idx], _branch_force(arch, theta, energy, idx)) for idx in _outward(theta))


def _branch_force(arch: Architecture, theta, energy, idx):
    """N_s (N/m) along one branch ``idx`` of the grid (see branch_forces)."""
    return np.gradient(energy[idx], theta[idx]) / _area_ratio(arch, theta[idx])


def shear_force(arch: Architecture, theta, energy):
    """N_s (N/m) on the grid θ (see branch_forces); at θ = 0 the negative side's value."""
    return _branchwise(theta, lambda idx: _branch_force(arch, theta, energy, idx))


def summed(arch: Architecture, theta_rad=None) -> dict:
    """energy_terms plus "total" W (J/m²) and N_s per term and in total (N/m): keys
    ``ns_<term>`` and ``ns_total``."""
    terms = energy_terms(arch, theta_rad)
    theta = terms["theta"]
    terms["total"] = sum(terms[t] for t in TERMS)
    for t in (*TERMS, "total"):
        terms[f"ns_{t}"] = shear_force(arch, theta, terms[t])
    return terms


# ----------------------------------------------------------------------------- zero-force angle

#: Grid half-range (deg) on which zero-force angles are sought.
ZERO_SEARCH_DEG = 40.0


def _zero_force(theta, total):
    """γ0 (deg): walking downhill on the summed energy from θ = 0 (the knitted state) to
    the first local minimum, refined within the grid step (see below). A fabric whose
    stitch friction resists more than the stitch tension pulls stays at 0."""
    k = int(np.argmin(np.abs(theta)))
    step = -1 if total[k - 1] < total[k] else 1 if total[k + 1] < total[k] else 0
    if step == 0:
        return 0.0
    while 0 < k + step < theta.size - 1 and total[k + step] < total[k]:
        k += step
    if not 0 < k + step < theta.size - 1:
        raise ValueError(f"the zero-force angle lies beyond ±{np.rad2deg(abs(theta[k])):g} deg")
    # the slopes of the two grid steps next to the minimum (at their midpoints) change sign:
    # their zero, by linear interpolation, is the minimum to within one grid step
    down, up = total[k] - total[k - 1], total[k + 1] - total[k]
    if up - down <= 0.0:
        return float(np.rad2deg(theta[k]))
    h = theta[k + 1] - theta[k]
    return float(np.rad2deg(theta[k] - h / 2.0 + h * (-down) / (up - down)))


class _FixedTerms:
    """The terms that do not depend on the stitch pre-strain, on the γ0 search grid."""

    def __init__(self, arch: Architecture):
        self.arch = arch
        self.theta = theta_grid(ZERO_SEARCH_DEG)
        self.w = _compaction(arch, self.theta) + _crossover(arch, self.theta)

    def zero_force_angle(self, prestrain: float) -> float:
        arch = replace(self.arch, prestrain=float(prestrain))
        w_t, w_f, _ = _stitch_terms(arch, self.theta)
        return _zero_force(self.theta, self.w + w_t + w_f)


def zero_force_angle(arch: Architecture) -> float:
    """γ0 (deg): the rest state of the summed energy next to θ = 0 (< 0 when the
    pre-strained stitch pulls harder than its friction holds; see _zero_force)."""
    return _FixedTerms(arch).zero_force_angle(arch.prestrain)


@dataclass(frozen=True)
class ZeroForceTable:
    """Pre-strain -> zero-force angle γ0 of one architecture, tabulated once, vectorised.

    ``prestrain`` (fractions, from 0 to ``max_prestrain``) and ``gamma0_deg`` are the
    nodes; between them a monotone cubic (PCHIP). A thread with ε0 <= 0 is slack at
    θ = 0, so γ0 = 0 there exactly (the remaining terms are least at 0); values above
    ``max_prestrain`` are refused.
    """

    prestrain: np.ndarray
    gamma0_deg: np.ndarray

    @property
    def max_prestrain(self) -> float:
        return float(self.prestrain[-1])

    def __call__(self, prestrain):
        """γ0 (deg) for any array of pre-strains (fractions)."""
        from scipy.interpolate import PchipInterpolator

        e = np.asarray(prestrain, dtype=float)
        if e.size and not np.nanmax(e) <= self.max_prestrain:
            raise ValueError(f"stitch pre-strain {np.nanmax(e):g} is beyond the mapped range "
                             f"[0, {self.max_prestrain:g}]")
        return PchipInterpolator(self.prestrain, self.gamma0_deg)(np.maximum(e, 0.0))


def material_zero_force_table(material) -> ZeroForceTable:
    """The pre-strain -> γ0 map of a card derived from an architecture (its [architecture.inputs]).

    Range of validity: the card is the architecture's curve at its own pre-strain ε*,
    measured from its γ0*; a cell at ε0 is given that card shifted to γ0(ε0), i.e. the
    change of shape with ε0 is left out. For the FGE 106hd card (ε* = 0.384 %) the
    shifted card's energy stays within 5 % of the architecture's own (over ±45° from γ0,
    relative to W there) for 0.2 % <= ε0 <= 0.6 % and within 10 % for 0.1-0.8 %
    (γ0 -0.6 to -4.6°); at 1 % it is 14 %, at 2 % 28 %.
    """
    if material.architecture is None:
        raise ValueError(f"material {material.name!r} has no [architecture] record; derive its card from a fabric "
                         "architecture (uqdrape materials derive) to vary the stitch pre-strain")
    arch = architecture_from_document(material.architecture["inputs"], f"material {material.name!r} [architecture.inputs]")
    return zero_force_table(arch)


#: Pre-strains tabulated by zero_force_table: 0 to 3 % (γ0 to about -16 deg for the FGE
#: 106hd tricot), 0.1 % apart.
TABLE_PRESTRAINS = np.round(np.linspace(0.0, 0.03, 31), 6)


def zero_force_table(arch: Architecture, prestrains=TABLE_PRESTRAINS) -> ZeroForceTable:
    """Tabulate γ0(ε0) for the architecture (its own pre-strain is ignored)."""
    fixed = _FixedTerms(arch)
    e = np.asarray(prestrains, dtype=float)
    return ZeroForceTable(e, np.array([fixed.zero_force_angle(v) for v in e]))


# ----------------------------------------------------------------------------- calibration


def calibrate(arch: Architecture, *, zero_force_angle_deg=None, negative_ns=None, iterations=6) -> Architecture:
    """The architecture with ``beta`` and/or ``prestrain`` fitted to thesis targets.

    ``negative_ns`` = (angle deg > 0, N_s N/m): β such that the summed negative-branch
    N_s at −angle equals the value. σ_b (so the compaction and crossover terms) scales
    exactly as β⁻⁴ (see bulk_stress), so β = (K/(N − N_stitch))^¼ with K their N_s at
    β = 1. ``zero_force_angle_deg`` (< 0): the pre-strain whose γ0 equals it (brentq).
    The two fits are alternated until both hold (β barely moves γ0). The result's
    ``calibration`` records the targets and the fitted values.
    """
    record = dict(arch.calibration)
    for _ in range(iterations):
        before = (arch.beta, arch.prestrain)
        if negative_ns is not None:
            angle, target = (float(v) for v in negative_ns)
            theta = theta_grid(angle + 1.0)  # central differences at -angle, as in summed()
            at = int(np.argmin(np.abs(theta + math.radians(angle))))
            unit = replace(arch, beta=1.0)
            k_ns = -shear_force(unit, theta, _compaction(unit, theta) + _crossover(unit, theta))[at]
            w_t, w_f, _ = _stitch_terms(arch, theta)
            stitch = -shear_force(arch, theta, w_t + w_f)[at]
            if not target > stitch:
                raise ValueError(f"negative_ns target {target:g} N/m at -{angle:g} deg is not above the stitch "
                                 f"terms' {stitch:.3g} N/m there")
            arch = replace(arch, beta=float((k_ns / (target - stitch)) ** 0.25))
        if zero_force_angle_deg is not None:
            target = float(zero_force_angle_deg)
            fixed = _FixedTerms(arch)
            top = float(TABLE_PRESTRAINS[-1])
            if not fixed.zero_force_angle(top) < target < 0.0:
                raise ValueError(f"zero_force_angle_deg = {target:g} must lie in "
                                 f"({fixed.zero_force_angle(top):.3g}, 0) deg for this architecture")
            eps = brentq(lambda e: fixed.zero_force_angle(e) - target, 0.0, top, xtol=1e-9)
            arch = replace(arch, prestrain=float(eps))
        if negative_ns is None or zero_force_angle_deg is None:
            break
        if np.allclose((arch.beta, arch.prestrain), before, rtol=1e-10, atol=0.0):
            break
    if negative_ns is not None:
        record.update(beta=arch.beta, negative_ns_angle_deg=float(negative_ns[0]),
                      negative_ns_N_per_m=float(negative_ns[1]))
    if zero_force_angle_deg is not None:
        record.update(prestrain=arch.prestrain, zero_force_angle_deg=float(zero_force_angle_deg))
    return replace(arch, calibration=record)


# ----------------------------------------------------------------------------- derived card

#: N_s (N/m) at which a derived card's branch ends and locks: the top of the thesis's
#: positive-shear picture-frame axes for these fabrics (Figs 3.10, 3.12: 0-1000 N/m).
#: Beyond it the constant-thickness compaction is the near-vertical wall that the thesis
#: itself calls unrealistic (L7655-7663).
LOCK_FORCE_N_PER_M = 1000.0
#: Angles (deg, absolute θ) at which a card records each term's N_s (Fig 4.18); 0 is left
#: out because the friction terms jump there.
CONTRIBUTION_STEP_DEG = 5.0


def _card_branch(arch, sides, gamma0, sense, x_max):
    """Card points (x deg from γ0, N_s magnitudes as the Material weights them) of one branch,
    the branch's locking angle and the largest negative N_s clipped to 0 on it."""
    g0 = math.radians(gamma0)
    phi0 = math.radians(arch.phi0_deg)
    xs, ns = [], []
    clipped = 0.0
    for x in np.arange(0.0, x_max + 1e-9, CARD_STEP_DEG):
        t = g0 + sense * math.radians(x)
        on_plus = t > 0.0 or (t == 0.0 and sense > 0)
        grid, force = sides[0] if on_plus else sides[1]
        value = sense * float(np.interp(abs(t), np.abs(grid), force))
        # the Material integrates N_s · sin(2φ0 − sense·x)/sin 2φ0; the architecture's
        # work weight at θ = γ0 + sense·x is sin(2φ0 − θ)/sin 2φ0
        value *= math.sin(2.0 * phi0 - t) / math.sin(2.0 * phi0 - sense * math.radians(x))
        if value < 0.0:
            clipped = max(clipped, -value)
            value = 0.0
        xs.append(float(x))
        ns.append(round(value, 3) + 0.0)
        if value >= LOCK_FORCE_N_PER_M:
            break
    return xs, ns, xs[-1], clipped


def derive_card(arch: Architecture, *, name: str | None = None, source: str = "", terms=None) -> dict:
    """A material card document (TOML layout of uqdrape.material.cards) from the architecture.

    The branches start at the zero-force angle γ0 (x = θ − γ0, magnitudes), 1° apart, and
    end where N_s reaches LOCK_FORCE_N_PER_M, which is the locking angle of that branch.
    The summed energy of the thesis can fall briefly along a branch (stitch friction
    counted from θ = 0 outweighing a slackening stitch); there N_s is clipped to 0 and the
    largest clipped value is recorded (``terms``: ``summed(arch)`` if already computed).
    ``[architecture]`` records the inputs, the
    calibration, the model version, γ0 and each term's N_s every 5° (thesis Fig 4.18).
    """
    gamma0 = zero_force_angle(arch)
    terms = summed(arch) if terms is None else terms
    theta = terms["theta"]
    sides = branch_forces(arch, theta, terms["total"])
    end = float(np.rad2deg(theta[-1]))
    pos = _card_branch(arch, sides, gamma0, +1, end - gamma0)
    neg = _card_branch(arch, sides, gamma0, -1, end + gamma0)
    top = CONTRIBUTION_STEP_DEG * math.floor(end / CONTRIBUTION_STEP_DEG)
    angles = [float(a) for a in np.arange(-top, top + 1e-9, CONTRIBUTION_STEP_DEG)
              if a != 0.0 and gamma0 - neg[2] <= a <= gamma0 + pos[2]]
    at = np.deg2rad(angles)
    contributions = {"angle_deg": [float(a) for a in angles]}
    for term in (*TERMS, "total"):
        contributions[term] = [round(float(v), 3) + 0.0 for v in np.interp(at, theta, terms[f"ns_{term}"])]
    description = (f"derived from the fabric architecture {arch.name!r} (thesis ch. 4 model): "
                   f"{arch.description}").rstrip(": ")
    note = (f"Derived by uqdrape {MODEL_VERSION} from {source or arch.name}: stitch tension, stitch friction, "
            "lateral tow compaction and crossover friction summed at the energy level and differentiated "
            f"(Wiggers 2007, §4.3). Branches are measured from the zero-force angle {gamma0:.3f} deg; they end "
            f"where N_s reaches {LOCK_FORCE_N_PER_M:g} N/m (locking). Calibrated constants and their targets are "
            "under [architecture.calibration]. A model prediction, not measured data.")
    return {
        "name": name or f"{arch.name}_derived",
        "description": description,
        "note": note,
        "phi0_deg": float(arch.phi0_deg),
        "locking_angle_deg": pos[2],
        "locking_angle_neg_deg": neg[2],
        "bending_stiffness": DEFAULT_BENDING_STIFFNESS,
        "stitch_direction_deg": float(arch.phi0_deg),
        "shear": {"positive": {"angle_deg": pos[0], "ns": pos[1]},
                  "negative": {"angle_deg": neg[0], "ns": neg[1]}},
        "architecture": {
            "model": MODEL_VERSION,
            "source": source or arch.name,
            "zero_force_angle_deg": round(gamma0, 6),
            "clipped_ns_N_per_m": round(max(pos[3], neg[3]), 6),
            "inputs": architecture_document(arch),
            "calibration": dict(arch.calibration),
            "contributions": contributions,
        },
    }


# ----------------------------------------------------------------------------- files

#: File layout: (table, key) -> Architecture field. Top-level keys have table None.
_LAYOUT = {
    (None, "name"): "name", (None, "description"): "description", (None, "source"): "source",
    (None, "phi0_deg"): "phi0_deg", (None, "thickness_mm"): "thickness_mm",
    ("stitch", "length_mm"): "stitch_length_mm", ("stitch", "gauge"): "gauge",
    ("stitch", "lapping"): "lapping", ("stitch", "stiffness_N"): "stitch_stiffness_N",
    ("stitch", "tension_curve"): "tension_curve", ("stitch", "failure_strain"): "failure_strain",
    ("stitch", "friction"): "stitch_friction", ("stitch", "prestrain"): "prestrain",
    ("compaction", "vf0"): "vf0", ("compaction", "v0"): "v0", ("compaction", "va"): "va",
    ("compaction", "fibre_modulus_GPa"): "fibre_modulus_GPa", ("compaction", "beta"): "beta",
    ("crossover", "side_mm"): "crossover_side_mm", ("crossover", "friction"): "crossover_friction",
    ("crossover", "tow_shear_ratio"): "tow_shear_ratio",
}
_FILE_KEY = {f: (k if t is None else f"{t}.{k}") for (t, k), f in _LAYOUT.items()}
_CALIBRATION_KEYS = ("zero_force_angle_deg", "negative_ns", "from")
_STRINGS = ("name", "description", "source")


def architecture_document(arch: Architecture) -> dict:
    """The architecture in its file layout (all values resolved, no [calibration] table)."""
    doc = {}
    for (table, key), fname in _LAYOUT.items():
        value = getattr(arch, fname)
        if value is None or (fname in _STRINGS and not value):
            continue
        if fname == "lapping":
            value = list(value)
        elif fname == "tension_curve":
            value = {"strain": list(value[0]), "tension_N": list(value[1])}
        (doc if table is None else doc.setdefault(table, {}))[key] = value
    return doc


def _number(label, key, value, *, integer=False):
    ok = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok or not math.isfinite(value):
        raise ArchitectureError(f"{label}: {key} = {value!r} is invalid: must be {'an integer' if integer else 'a number'}")
    return value if integer else float(value)


def architecture_from_document(doc: dict, label: str, base_dir: Path | None = None, _chain=()) -> Architecture:
    """An Architecture from a file-layout document; ``label`` names the file in errors.

    ``"calibrate"`` for stitch.prestrain or compaction.beta fits it to the targets of
    ``[calibration]`` (zero_force_angle_deg, negative_ns = [angle, N_s]), or takes the
    fitted value of the architecture file named by ``calibration.from`` (relative to
    ``base_dir``).
    """
    tables = {"stitch", "compaction", "crossover", "calibration"}
    known = {k for t, k in _LAYOUT if t is None} | tables
    for key, value in doc.items():
        if key not in known:
            raise ArchitectureError(f"{label}: unknown key {key}; valid: {', '.join(sorted(known))}")
        if key in tables and not isinstance(value, dict):
            raise ArchitectureError(f"{label}: {key} must be a table [{key}]")
    kwargs, pending = {}, []
    for table in (None, "stitch", "compaction", "crossover"):
        data = doc if table is None else doc.get(table, {})
        valid = [k for t, k in _LAYOUT if t == table]
        for key, value in data.items():
            if table is None and key in tables:
                continue
            dotted = key if table is None else f"{table}.{key}"
            if key not in valid:
                raise ArchitectureError(f"{label}: unknown key {dotted}; valid in this table: {', '.join(valid)}")
            fname = _LAYOUT[(table, key)]
            if fname in _STRINGS:
                if not isinstance(value, str):
                    raise ArchitectureError(f"{label}: {dotted} = {value!r} is invalid: must be a string")
            elif fname == "lapping":
                if not isinstance(value, list):
                    raise ArchitectureError(f"{label}: {dotted} = {value!r} is invalid: must be a list of integers")
                value = tuple(_number(label, dotted, v, integer=True) for v in value)
            elif fname == "tension_curve":
                if not isinstance(value, dict) or set(value) != {"strain", "tension_N"}:
                    raise ArchitectureError(f"{label}: {dotted} must be a table with strain = [...] and tension_N = [...]")
                value = tuple(tuple(_number(label, f"{dotted}.{k}", v) for v in value[k]) for k in ("strain", "tension_N"))
            elif fname in ("prestrain", "beta") and value == "calibrate":
                pending.append(fname)
                continue
            else:
                value = _number(label, dotted, value)
            kwargs[fname] = value
    for fname in ("name", "stitch_length_mm", "gauge", "prestrain", "beta"):
        if fname not in kwargs and fname not in pending:
            raise ArchitectureError(f"{label}: {_FILE_KEY[fname]} is missing")
    if "tension_curve" in kwargs:
        kwargs.setdefault("stitch_stiffness_N", None)
    calibration = doc.get("calibration", {})
    for key in calibration:
        if key not in _CALIBRATION_KEYS:
            raise ArchitectureError(f"{label}: unknown key calibration.{key}; valid: {', '.join(_CALIBRATION_KEYS)}")
    if pending and not calibration:
        raise ArchitectureError(f"{label}: {_FILE_KEY[pending[0]]} = \"calibrate\" needs a [calibration] table")
    try:
        arch = Architecture(**{**kwargs, **{f: (0.0 if f == "prestrain" else 1.0) for f in pending}})
    except ArchitectureError as err:
        raise ArchitectureError(f"{label}: {str(err).replace(err.key, _FILE_KEY.get(err.key, err.key), 1) if err.key else err}") from None
    if not pending:
        return arch
    if "from" in calibration:
        ref = calibration["from"]
        if not isinstance(ref, str) or base_dir is None or not (Path(base_dir) / ref).is_file():
            raise ArchitectureError(f"{label}: calibration.from = {ref!r} is invalid: must name an architecture file "
                                    "next to this one")
        donor_path = (Path(base_dir) / ref).resolve()
        if donor_path in _chain:
            raise ArchitectureError(f"{label}: calibration.from = {ref!r} is invalid: the files' calibration.from "
                                    "entries form a cycle")
        donor = _load(donor_path, _chain)
        fitted = {f: getattr(donor, f) for f in pending}
        record = {f"{f}": fitted[f] for f in pending} | {"from": ref}
        return replace(arch, **fitted, calibration=record)
    targets = {}
    if "prestrain" in pending:
        if "zero_force_angle_deg" not in calibration:
            raise ArchitectureError(f"{label}: stitch.prestrain = \"calibrate\" needs calibration.zero_force_angle_deg")
        targets["zero_force_angle_deg"] = _number(label, "calibration.zero_force_angle_deg",
                                                  calibration["zero_force_angle_deg"])
    if "beta" in pending:
        pair = calibration.get("negative_ns")
        if not (isinstance(pair, list) and len(pair) == 2):
            raise ArchitectureError(f"{label}: compaction.beta = \"calibrate\" needs calibration.negative_ns = "
                                    "[angle_deg, N_s N/m]")
        targets["negative_ns"] = tuple(_number(label, "calibration.negative_ns", v) for v in pair)
    try:
        return calibrate(arch, **targets)
    except ValueError as err:
        raise ArchitectureError(f"{label}: calibration: {err}") from None


def _architectures_dir() -> Path:
    return Path(str(resources.files("uqdrape.material").joinpath("architectures")))


def available_architectures() -> list[str]:
    """Names of the architecture files shipped with uqdrape (sorted)."""
    return sorted(p.stem for p in _architectures_dir().glob("*.toml"))


def load_architecture(name_or_path) -> Architecture:
    """Read an architecture TOML file, or a shipped one by name (``fge106hd``, ...)."""
    text = str(name_or_path)
    path = _architectures_dir() / f"{text}.toml" if text in available_architectures() else Path(text)
    if not path.is_file():
        raise ArchitectureError(f"{path}: architecture file not found (shipped: {', '.join(available_architectures())})")
    return _load(path, ())


def _load(path: Path, chain) -> Architecture:
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ArchitectureError(f"{path}: not valid TOML ({exc})") from None
    return architecture_from_document(doc, str(path), path.parent, (*chain, path.resolve()))
