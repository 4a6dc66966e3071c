"""From a measured fibre angle to the model's input: the zero-energy shear angle γ0.

The decision, used by every calibration in uqdrape:

- **What a measurement is.** A fibre of set k measured at plan angle θ (deg from the
  sample's x axis) deviates from its nominal direction by δ_k = θ − φ_k, wrapped into
  (−90°, 90°] (a fibre is a line); φ_1 = ``fibre1_deg`` (45° for the ±45° non-crimp
  fabrics of the thesis) and φ_2 = φ_1 + 90°.
- **What it means for the model.** The model's shear is 90° minus the angle between the
  +fibre-1 and +fibre-2 edges (README, "Shear sign"), so with fibre k rotated by δ_k the
  cell's rest shear is γ0 = δ_1 − δ_2. A measured point gives one set's angle only; we
  read it as **that set rotating against the other**, held at its nominal direction by the
  stitch and the neighbouring tows: γ0 = δ_1 for a set-1 point and γ0 = −δ_2 for a set-2
  point, and points of both sets are samples of the one γ0 field. This is the reading the
  material cards already use: Table 5.1's mean 42.7° (a set-1 fibre from the weft datum)
  is γ0 = −2.3°, the zero-force angle FGE 106hd's stitch pre-strain is calibrated to
  (README, "What is calibrated"); the thesis puts this mean offset down to the stitch
  pre-tension, so the calibrated **mean** is the stitch's rest shear and the **sd** and
  correlation lengths its local scatter. (Both sets rotating oppositely would double γ0
  for the same reading; nothing in the thesis's data tells the two apart.)
- **What it is not.** A rigid rotation of both sets (δ_1 = δ_2) shears nothing: it is the
  study's misalignment (``[uncertainty.orientation]``), and one set's angles cannot
  separate it from γ0. It is not calibrated here. Where both sets were measured at the
  same spots (points of the two sets within ``SAME_SPOT_MM``), the data can tell: if the
  sets turn together there (the spots' mean rotation (δ_1 + δ_2)/2 scatters more than
  their difference δ_1 − δ_2), the reading above would take +δ and −δ at one spot for
  two samples of γ0 and fit the rotation's scatter away (2° of it came out as
  sd_deg = 0.002), so the points are refused, in one line saying so and what to do,
  rather than calibrated to a block that hides the scatter.
- **Where.** Positions are turned into coordinates along fibre 1 and fibre 2 (nominal
  directions, mm), the axes of the study's γ0 lattice (``uqdrape.stochastic.fields``:
  axis 0 along fibre 1, axis 1 along fibre 2), so a fitted ``length_mm = [L1, L2]`` is
  what ``[uncertainty.zero_angle] length_mm`` means.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .points import AnglePoints, PointsError

#: Largest deviation of a measured fibre from its nominal direction accepted (deg): more
#: is a different angle convention (e.g. set 2 given as its acute angle from the weft),
#: not fabric scatter.
MAX_DEVIATION_DEG = 45.0


def wrap_deg(angle_deg) -> np.ndarray:
    """An angle between lines, in (−90, 90] degrees."""
    return 90.0 - np.mod(90.0 - np.asarray(angle_deg, dtype=float), 180.0)


#: Points of the two fibre sets closer than this (mm) are read as one spot measured on both:
#: a tow is several mm wide, so two readings nearer than that see the same tows.
SAME_SPOT_MM = 1.0
#: Fewest spots measured on both sets whose rotation and difference are compared.
MIN_SPOTS = 3


def zero_angle_deg(points: AnglePoints, fibre1_deg: float = 45.0) -> np.ndarray:
    """γ0 (deg) at each measured point: δ_1 for a set-1 fibre, −δ_2 for a set-2 fibre.
    A deviation beyond MAX_DEVIATION_DEG raises PointsError naming its row, and so do
    spots measured on both sets that show a rigid rotation (``check_rigid_rotation``)."""
    delta = _deviation_deg(points, fibre1_deg)
    check_rigid_rotation(points, delta)
    return np.where(points.fibre_set == 1, delta, -delta)


def check_rigid_rotation(points: AnglePoints, delta_deg: np.ndarray) -> None:
    """Refuse (PointsError) points whose spots measured on both sets (each set-1 point and
    the nearest set-2 point within SAME_SPOT_MM, at least MIN_SPOTS of them) show the two
    sets turning together: the sd of the spots' rotation (δ_1 + δ_2)/2 above the sd of
    δ_1 − δ_2, the γ0 the model gives a spot (module docstring). ``delta_deg``: each point's δ."""
    one, two = points.fibre_set == 1, points.fibre_set == 2
    if one.sum() < MIN_SPOTS or two.sum() < MIN_SPOTS:
        return
    tree = cKDTree(np.column_stack([points.x_mm[two], points.y_mm[two]]))
    distance, nearest = tree.query(np.column_stack([points.x_mm[one], points.y_mm[one]]),
                                   distance_upper_bound=SAME_SPOT_MM)
    paired = np.isfinite(distance)
    if paired.sum() < MIN_SPOTS:
        return
    d1, d2 = delta_deg[one][paired], delta_deg[two][nearest[paired]]
    turn, shear = np.std((d1 + d2) / 2, ddof=1), np.std(d1 - d2, ddof=1)
    if turn <= shear:
        return
    raise PointsError(f"{points.source}: at {int(paired.sum())} spots measured on both fibre sets (points within "
                      f"{SAME_SPOT_MM:g} mm) the sets turn together: the spots' rotation (d1 + d2)/2 has sd {turn:.3g} "
                      f"deg, their gamma0 = d1 - d2 sd {shear:.3g} deg (d: a fibre's deviation from its set's nominal "
                      "direction); a rigid rotation is misalignment, not gamma0: put its sd in "
                      "[uncertainty.orientation], and calibrate gamma0 from one fibre set's angles or from one set-1 "
                      "point per spot at angle_deg = fibre1_deg + d1 - d2", points.source, "fibre_set")


def _deviation_deg(points: AnglePoints, fibre1_deg: float) -> np.ndarray:
    """δ (deg) of each measured point from its set's nominal direction; beyond
    MAX_DEVIATION_DEG raises PointsError naming its row."""
    nominal = np.where(points.fibre_set == 1, fibre1_deg, fibre1_deg + 90.0)
    delta = wrap_deg(points.angle_deg - nominal)
    far = np.flatnonzero(np.abs(delta) > MAX_DEVIATION_DEG)
    if far.size:
        i = far[0]
        raise PointsError(f"{points.source}: row {points.rows[i]}: column 'angle_deg' = {points.angle_deg[i]:g} is "
                          f"{delta[i]:+.1f} deg from fibre set {points.fibre_set[i]}'s nominal {nominal[i]:g} deg "
                          f"(valid: within {MAX_DEVIATION_DEG:g} deg of it); angle_deg is the fibre's plan direction, "
                          "deg anticlockwise from x, and fibre 1's nominal direction is fibre1_deg",
                          points.source, "angle_deg")
    return delta


def fibre_coordinates(x_mm, y_mm, fibre1_deg: float = 45.0) -> tuple[np.ndarray, np.ndarray]:
    """(a, b): the coordinates of plan points (``x_mm``, ``y_mm``) along nominal fibre 1
    and along fibre 2, mm."""
    phi = np.deg2rad(fibre1_deg)
    x, y = np.asarray(x_mm, dtype=float), np.asarray(y_mm, dtype=float)
    return x * np.cos(phi) + y * np.sin(phi), -x * np.sin(phi) + y * np.cos(phi)
