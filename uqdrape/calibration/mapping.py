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
  separate it from γ0. It is not calibrated here.
- **Where.** Positions are turned into coordinates along fibre 1 and fibre 2 (nominal
  directions, mm), the axes of the study's γ0 lattice (``uqdrape.stochastic.fields``:
  axis 0 along fibre 1, axis 1 along fibre 2), so a fitted ``length_mm = [L1, L2]`` is
  what ``[uncertainty.zero_angle] length_mm`` means.
"""

from __future__ import annotations

import numpy as np

from .points import AnglePoints, PointsError

#: Largest deviation of a measured fibre from its nominal direction accepted (deg): more
#: is a different angle convention (e.g. set 2 given as its acute angle from the weft),
#: not fabric scatter.
MAX_DEVIATION_DEG = 45.0


def wrap_deg(angle_deg) -> np.ndarray:
    """An angle between lines, in (−90, 90] degrees."""
    return 90.0 - np.mod(90.0 - np.asarray(angle_deg, dtype=float), 180.0)


def zero_angle_deg(points: AnglePoints, fibre1_deg: float = 45.0) -> np.ndarray:
    """γ0 (deg) at each measured point: δ_1 for a set-1 fibre, −δ_2 for a set-2 fibre.
    A deviation beyond MAX_DEVIATION_DEG raises PointsError naming its row."""
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
    return np.where(points.fibre_set == 1, delta, -delta)


def fibre_coordinates(x_mm, y_mm, fibre1_deg: float = 45.0) -> tuple[np.ndarray, np.ndarray]:
    """(a, b): the coordinates of plan points (``x_mm``, ``y_mm``) along nominal fibre 1
    and along fibre 2, mm."""
    phi = np.deg2rad(fibre1_deg)
    x, y = np.asarray(x_mm, dtype=float), np.asarray(y_mm, dtype=float)
    return x * np.cos(phi) + y * np.sin(phi), -x * np.sin(phi) + y * np.cos(phi)
