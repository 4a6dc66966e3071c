"""Known values the tests compare against, each with where it comes from.

Every constant has a ``#:`` line above it starting with its kind of source:

- ``closed form:`` a formula anyone can evaluate;
- ``thesis:`` a number printed in Wiggers (2007), located in ../shared/reference/thesis-notes.md;
- ``hand:`` worked by hand in thesis-notes.md ([MY CHECK] entries);
- ``regression: produced by commit <hash>``: the code's own output on that commit, kept so
  that a change of behaviour shows. A regression value is only as right as the code that
  produced it; the tests beside it check the physics (symmetries, orders, closed forms).

Tolerances belong to the tests: a geodesic drape reproduces to about 1e-9, so its values
are compared at rel=1e-6; an energy drape is only as exact as its minimiser (1e-3 deg).
Units are in the names.
"""

from __future__ import annotations

import numpy as np

# -- sensitivity: the Ishigami function sin x1 + a sin² x2 + b x3⁴ sin x1, x ~ U(−π, π)³ --
_A, _B = 7.0, 0.1
_V1 = 0.5 * (1 + _B * np.pi**4 / 5) ** 2
_V2 = _A**2 / 8
_V13 = _B**2 * np.pi**8 * 8 / 225
_V = _V1 + _V2 + _V13
#: closed form: Ishigami (a = 7, b = 0.1) first-order indices V1/V, V2/V, 0 (0.3139, 0.4424, 0)
ISHIGAMI_S1 = np.array([_V1, _V2, 0.0]) / _V
#: closed form: Ishigami (a = 7, b = 0.1) total indices (V1 + V13)/V, V2/V, V13/V (0.5576, 0.4424, 0.2437)
ISHIGAMI_ST = np.array([_V1 + _V13, _V2, _V13]) / _V

# -- drape: geodesic nets --------------------------------------------------------------
#: regression: produced by commit f2b25f1 (largest cell shear, deg, Hemisphere(100), s = 5 mm, 16 rings)
HEMISPHERE_MAX_CELL_SHEAR_DEG = 33.7342404
#: regression: produced by commit 38a9b35 (shear, deg, Hemisphere(100) node (35/s, 35/s), s = 5, 2.5, 1.25 mm)
HEMISPHERE_NODE_SHEAR_DEG = (7.012555320879893, 7.012805716050033, 7.01286730715229)
#: regression: produced by commit 38a9b35 (distance, mm, of that node along the ++ max-shear line)
HEMISPHERE_NODE_DISTANCE_MM = (50.483992516436096, 50.48764931512616, 50.48856339008301)
#: regression: produced by commit 38a9b35 (max |cell shear|, deg, 30 deg cone flank, s = 10, 5, 2.5, 1.25 mm)
CONE_FLANK_MAX_CELL_SHEAR_DEG = (0.2597462514043542, 0.07658780002571415, 0.02151008905528361, 0.005662752555169073)
#: regression: produced by commit 9bccb2a (max node position gap, mm, hemisphere_r50.stl as a mesh mould vs Hemisphere(50, 60); 0.0747 as a height field)
STL_HEMISPHERE_POSITION_GAP_MM = 0.06057619716851982
#: regression: produced by commit 9bccb2a (max node shear gap, deg, of the same pair; 0.0920 before)
STL_HEMISPHERE_SHEAR_GAP_DEG = 0.11000472205644485

# -- drape: blank-holder energy --------------------------------------------------------
#: regression: produced by commit 333d6f2 (blank-holder energy, J, at skew 0 and 55 deg, per model)
SKEW_BLANKHOLDER_ENERGY_J = {"radial": (2.44411838, 4.04760113), "slip": (2.49354203, 5.83760009)}
#: Fig 5.6 set-up (Wiggers 2007) over the whole dome (rings 31, radial model); issue 38's "4.93 -> 6.64 J"
#: regression: produced by commit 4e5c80e (blank-holder energy, J, at skew 0 and 55 deg)
FIG56_BLANKHOLDER_ENERGY_J = (4.93266595, 6.64426745)
#: regression: produced by commit 333d6f2 (nose cone: - minus + quadrants' mean |shear|, deg, per force)
NOSE_CONE_QUADRANT_GAP_DEG = {"radial": (42.50103, 35.67999, 30.96208, 27.48478, 0.36888),
                              "slip": (42.50103, 25.75022, 19.12477, 15.38897, 0.11152)}

# -- gallery: flat-plate spacing studies, first 40 realisations of the shipped seeds ---
#: regression: produced by commit f2b25f1 (plate-spacing: mean over rings 1-5 of the node shear sd, deg)
PLATE_IID_INNER_SD_DEG = 1.098776
#: regression: produced by commit f2b25f1 (plate-spacing: mean over rings 25-29 of the node shear sd, deg)
PLATE_IID_OUTER_SD_DEG = 3.555542
#: regression: produced by commit 38a9b35 (plate-spacing: mean over realisations of the mean cell shear, deg)
PLATE_IID_MEAN_CELL_SHEAR_DEG = -4.683114261928699
#: regression: produced by commit 38a9b35 (plate-correlated-spacing: the same mean, deg)
PLATE_CORRELATED_MEAN_CELL_SHEAR_DEG = -0.8761170408821701

# -- export ----------------------------------------------------------------------------
#: regression: produced by commit 38a9b35 (FE interpolation error of a smooth field, s = 4 mm over s = 2 mm)
FE_INTERPOLATION_ERROR_RATIO = 3.997710975942923

# -- materials -------------------------------------------------------------------------
#: closed form: N = 250 x + 600 x^4 at x = 1 (ebxhd936_like.toml's positive curve), N/m at 60 deg
EBXHD936_LIKE_NS_60_DEG_N_PER_M = 850.0

# -- NCF architecture (thesis ch. 4), FGE 106hd: tricot, s_l 2.5 mm, s_g 25.4/6 mm, s_t 2 mm
#: hand: thesis-notes §2.3, s_L(0) = 2·2·(2.5 + 2) + 2·sqrt(2.5² + 4.2333²), mm (to 3 decimals)
FGE_STITCH_LENGTH_MM = 27.833
#: hand: thesis-notes §2.3, A_s = 2·2.5·4.2333, mm² (to 4 decimals)
FGE_UNIT_AREA_MM2 = 21.1667
#: closed form: 100 (s_L(θ)/s_L(0) − 1), Eq 4.1, 4.2, 4.6, at θ = 15, 30, 45, 60, −30 deg, % (4 decimals)
FGE_STITCH_STRAIN_PCT = (2.1011, 3.5161, 4.3559, 4.7704, -6.4891)
#: regression: produced by commit 38a9b35 (zero pre-strain: the stitch tension's peak, deg and N/m; 33e46c7: 35.62)
FGE_STITCH_TENSION_PEAK = (27.5, 35.61959053369167)
#: regression: produced by commit 38a9b35 (zero-force angle, deg, at pre-strain 0.005, 0.01; 33e46c7: -2.975, -5.724)
FGE_ZERO_FORCE_ANGLE_DEG = {0.005: -2.9748899567414258, 0.01: -5.7243088750265185}
#: closed form: acos(V_f0 / V_a), V_f0 = 0.35, V_a = π/(2√3) (hexagonal packing), deg
FGE_LOCKING_ANGLE_DEG = 67.30
#: regression: produced by commit 38a9b35 (crossover friction / compaction N_s at 30, 45, 60 deg; 33e46c7: 4 digits)
FGE_CROSSOVER_TO_COMPACTION = {30.0: 0.045604175743741614, 45.0: 0.013106498105218677, 60.0: 0.003074390634490885}
#: regression: produced by commit 33e46c7 (+N_s(30 deg) / −N_s(−30 deg), shipped 2.5 and 5 mm stitches)
FGE_ASYMMETRY_AT_30_DEG = {"fge106hd": 2221, "fge106hd_5mm": 15200}
#: regression: produced by commit 38a9b35 (grid angle, deg, where the 5 mm stitch reaches 17 % strain)
FGE_5MM_STITCH_FAILURE_DEG = 44.35
#: thesis: Table 5.1, mean fibre angle 2.3 deg below 45 (L9189-9195): the calibration target, deg
FGE_ZERO_FORCE_TARGET_DEG = -2.3
#: thesis: Fig B.11, BE negative shear force tops at 60 N/m (at 60 deg): the calibration target, N/m
FGE_NEGATIVE_NS_TARGET_N_PER_M = 60.0
#: regression: produced by commit 33e46c7 (fge106hd.toml's calibrated stitch pre-strain and McBride beta)
FGE_CALIBRATED = {"prestrain": 0.003844, "beta": 463.80}
