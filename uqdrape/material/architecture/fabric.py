"""The fabric architecture: a stitched ±φ0 non-crimp fabric's inputs, checked (thesis §4.3)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: Hexagonal packing limit of aligned fibres, π/(2√3) (thesis Fig 4.4).
HEXAGONAL_VA = math.pi / (2.0 * math.sqrt(3.0))


class ArchitectureError(ValueError):
    """A bad architecture: ``key`` is the offending Architecture field, ``value`` its value and
    ``why`` what is valid (a file reader names the file's key instead, uqdrape.files style)."""

    def __init__(self, key: str, value, why: str):
        super().__init__(f"{key} = {value!r} is invalid: {why}")
        self.key, self.value, self.why = key, value, why


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


#: Upper ends of the positive sizes (mm, needles per inch, GPa, McBride's beta): far past
#: any stitched fabric (the shipped ones: 1.65-5 mm stitches, gauge 6, 2 mm thick, 1.87 mm
#: crossovers, 72 GPa, beta 464), short of the overflow of the model's powers (beta^4, side^2).
_MOST = {"stitch_length_mm": 100.0, "gauge": 100.0, "thickness_mm": 100.0, "crossover_side_mm": 100.0,
         "fibre_modulus_GPa": 1000.0, "beta": 1e6}


def _validate(a: Architecture) -> None:
    def bad(key, why):
        raise ArchitectureError(key, getattr(a, key), why)

    for key, most in _MOST.items():
        value = getattr(a, key)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and 0 < value <= most):
            bad(key, f"must be a number in (0, {most:g}]")
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
        bad("stitch_stiffness_N", "give the stitch yarn law as exactly one of a linear stiffness or a tension curve")
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

