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

Modules: ``fabric`` (the Architecture and its checks), ``grid`` (the θ grid), ``geometry``
(stitch segments), ``stitch`` (tension and friction), ``compaction``, ``crossover``,
``model`` (the sum and N_s), ``zero_force`` (γ0 and its pre-strain table),
``calibrate``, ``reader`` (architecture files) and ``card`` (derived cards). The names
below are the public interface.
"""

from .calibrate import calibrate
from .card import CARD_STEP_DEG, CONTRIBUTION_STEP_DEG, LOCK_FORCE_N_PER_M, derive_card, material_zero_force_table
from .compaction import bulk_stress, fibre_volume_fraction
from .crossover import CROSSOVER_ELEMENTS, CROSSOVER_STEP_DEG
from .fabric import HEXAGONAL_VA, Architecture, ArchitectureError
from .geometry import stitch_length, stitch_segments, stitch_strain
from .grid import GRID_LIMIT_DEG, GRID_STEP_DEG, theta_grid
from .model import MODEL_VERSION, TERMS, branch_forces, energy_terms, shear_force, summed
from .reader import architecture_document, architecture_from_document, available_architectures, load_architecture
from .zero_force import TABLE_PRESTRAINS, ZERO_SEARCH_DEG, ZeroForceTable, zero_force_angle, zero_force_table

__all__ = [
    "CARD_STEP_DEG", "CONTRIBUTION_STEP_DEG", "CROSSOVER_ELEMENTS", "CROSSOVER_STEP_DEG", "GRID_LIMIT_DEG",
    "GRID_STEP_DEG", "HEXAGONAL_VA", "LOCK_FORCE_N_PER_M", "MODEL_VERSION", "TABLE_PRESTRAINS", "TERMS",
    "ZERO_SEARCH_DEG", "Architecture", "ArchitectureError", "ZeroForceTable", "architecture_document",
    "architecture_from_document", "available_architectures", "branch_forces", "bulk_stress", "calibrate",
    "derive_card", "energy_terms", "fibre_volume_fraction", "load_architecture", "material_zero_force_table",
    "shear_force", "stitch_length", "stitch_segments", "stitch_strain", "summed", "theta_grid",
    "zero_force_angle", "zero_force_table",
]
