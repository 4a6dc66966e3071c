"""Shear-test specimens -> a normalised material card: each specimen fitted, normalised
and cut to its valid range; the specimens of a branch averaged, their sd recorded.

Per specimen (rules recorded in the card's [sheartest] table):

1. θ: the measured angle where the CSV has one, else the kinematic θ of the rig
   (picture frame Eq 3.5, bias extension Eq 3.19). Rows after the largest θ are the
   unloading and are not used.
2. Valid range: from 0 to the smallest of max_angle_deg, the largest θ tested and, with a
   measured angle, the divergence angle (`fit.divergence_end`: measured and kinematic θ
   apart by more than max_divergence_deg).
3. Friction jump: rows below jump_deg are not fitted; the fit's value at θ = 0 is the
   friction offset F0 (N), kept in the curve (``friction = "keep"``, the thesis's choice)
   or subtracted from it (``"subtract"``).
4. The force column F(θ) is fitted by the monotone spline of `fit.monotone_fit`, then
   normalised to N_s(θ) (N/m) as the rig file's ``force_convention`` says: a crosshead
   force (N) by the rig, exactly (PF Eq 3.1; BE the W' form); F/L (N/m) by
   1/(2 cos(φ0 − θ/2)) (Eq 3.1); F_s/L (N/m) as it is. The offset F0 and the fit's
   residual are in the column's unit ([sheartest] force_unit).

A branch's card curve is the mean of its specimens' N_s on angles 0, step, 2·step, ...
up to the smallest valid end; [scatter.<branch>] holds their sample sd (n − 1) there.
Negative-branch forces are magnitudes; without negative specimens the card is symmetric.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fit import METHOD, MonotoneFit, divergence_end, monotone_fit
from .reader import BRANCHES, MIN_ROWS, RigFile, ShearTestError, Specimen


#: Least rise of a specimen's fitted force over its valid range, in multiples of the
#: fit's residual RMS: less is a flat, falling or noise-only record, not a shear test.
RISE_OVER_NOISE = 3.0


@dataclass(frozen=True)
class SpecimenFit:
    """One specimen fitted: θ of its rows (rad), which rows were fitted, the angle source
    ("measured" or "kinematic"), the valid end (rad) and the rule that set it, the force
    fit (N against rad) and the friction offset F0 (N)."""

    specimen: Specimen
    theta: np.ndarray
    used: np.ndarray
    angle_source: str
    end: float
    end_rule: str
    fit: MonotoneFit
    offset_n: float
    subtract: bool

    def force(self, theta):
        """The fitted crosshead force (N) at θ (rad), less F0 if friction is subtracted."""
        return self.fit(theta) - (self.offset_n if self.subtract else 0.0)

    def shear_force(self, theta):
        """The specimen's normalised N_s (N/m) at θ (rad), >= 0."""
        return np.maximum(self.specimen.shear_force(self.force, theta), 0.0)

    def points(self):
        """The fitted rows normalised one by one: (θ (rad), N_s (N/m)), friction as in the fit."""
        theta = self.theta[self.used]
        force = self.specimen.data.force_n[self.used] - (self.offset_n if self.subtract else 0.0)
        return theta, self.specimen.pointwise_shear_force(force, theta, self.force)


@dataclass(frozen=True)
class CardFit:
    """The result of `fit_card`: the card document, the specimen fits and warnings."""

    doc: dict
    fits: list
    warnings: list


def fit_specimen(specimen: Specimen, options: dict) -> SpecimenFit:
    """Fit one specimen by the rules of this module's docstring."""
    data, rig = specimen.data, specimen.rig
    kinematic = rig.shear_angle(data.displacement_mm)
    measured = data.angle_deg is not None
    bad = np.nonzero(np.isnan(kinematic))[0]
    if bad.size and not measured:  # with a measured angle, past the limit is diverged
        limit = float(rig.displacement(rig.max_angle()))
        data.fail(bad[0], "displacement", f"{data.displacement_mm[bad[0]]:g} mm is beyond the rig's geometric "
                                          f"limit of {limit:.4g} mm (tows parallel)")
    theta = np.deg2rad(data.angle_deg) if measured else kinematic
    ends = {"max_angle_deg": np.deg2rad(options["max_angle_deg"]), "end of data": float(np.max(theta))}
    if measured:
        diverged = divergence_end(theta, kinematic, np.deg2rad(options["max_divergence_deg"]))
        if diverged is not None:
            ends["divergence"] = diverged
    rule = min(ends, key=ends.get)
    end = ends[rule]
    loading = np.arange(theta.size) <= np.argmax(theta)
    used = loading & (theta >= np.deg2rad(options["jump_deg"])) & (theta <= end)
    if used.sum() < MIN_ROWS:
        raise ShearTestError(
            f"{data.path}: only {int(used.sum())} rows have shear between jump_deg = {options['jump_deg']:g} and the "
            f"valid end {np.rad2deg(end):.3g} deg ({rule}); a fit needs at least {MIN_ROWS}", data.path)
    fit = monotone_fit(theta[used], data.force_n[used], end, options["knots"])
    start = float(np.min(theta[used]))
    rise = float(fit(end) - fit(start))
    unit = specimen.force_unit
    if not fit(end) > 0 or not rise > RISE_OVER_NOISE * fit.residual_rms:
        raise ShearTestError(
            f"{data.path}: the force does not rise with shear: {float(fit(start)):.4g} {unit} at "
            f"{np.rad2deg(start):.3g} deg to {float(fit(end)):.4g} {unit} at {np.rad2deg(end):.3g} deg, scatter "
            f"{fit.residual_rms:.3g} {unit}; a shear test's force is positive and grows with the angle (check that "
            f"[columns] force names the force, in {unit}, and the rows are the loading)", data.path)
    return SpecimenFit(specimen, theta, used, "measured" if measured else "kinematic", end, rule, fit,
                       float(fit(0.0)), options["friction"] == "subtract")


#: How the card's N_s = F_s/L (N/m) came from the force column, per force_convention
#: (a crosshead force: per test).
_NORMALISATION = {
    "picture_frame": "picture frame: N_s = F / (2 L cos(phi0 - theta/2)) (Eq 3.1, 3.16)",
    "bias_extension": "bias extension: exact energy balance (2 kappa - 3) W'(theta) + W'(theta/2) = g(theta), "
                      "N_s = W' sin(2 phi0) / sin(2 phi0 - theta)",
    "F/L": "force column is F/L (N/m, Eq 3.16): N_s = (F/L) / (2 cos(phi0 - theta/2)) (Eq 3.1)",
    "F_s/L": "force column is N_s = F_s/L (N/m, Eq 3.1 over L): used as it is",
}


def _grid(end_deg: float, step_deg: float) -> np.ndarray:
    """Angles 0, step, ... below ``end_deg`` (deg), and ``end_deg`` itself."""
    grid = np.arange(0.0, end_deg - 1e-6 * step_deg, step_deg)
    return np.append(grid, end_deg)


def fit_card(rig_file: RigFile, name: str, rig_label: str) -> CardFit:
    """The card of every specimen of ``rig_file``, named ``name``; ``rig_label`` is how the
    card records the rig file."""
    options = rig_file.fit
    fits = [fit_specimen(s, options) for s in rig_file.specimens]
    warnings = [f"{f.specimen.data.path}: kappa = {f.specimen.rig.kappa:.3g} < 2: the energy normalisation is "
                "ill-conditioned (errors near 0 deg grow up the curve); the thesis asks for kappa >= 2"
                for f in fits if rig_file.test == "bias_extension" and rig_file.force_convention == "crosshead"
                and f.specimen.rig.kappa < 2.0]
    shear, scatter, record = {}, {}, {}
    for branch in BRANCHES:
        group = [f for f in fits if f.specimen.branch == branch]
        if not group:
            continue
        end_deg = float(np.rad2deg(min(f.end for f in group)))
        angles = _grid(end_deg, options["step_deg"])
        curves = np.array([f.shear_force(np.deg2rad(angles)) for f in group])
        shear[branch] = {"angle_deg": _round(angles), "ns": _round(curves.mean(axis=0))}
        if len(group) > 1:
            scatter[branch] = {"angle_deg": _round(angles), "ns_sd": _round(curves.std(axis=0, ddof=1)),
                               "specimens": len(group)}
        record[branch] = {
            "files": [str(f.specimen.data.path.name) for f in group],
            "angle_source": [f.angle_source for f in group],
            "valid_end_deg": _round([np.rad2deg(f.end) for f in group]),
            "end_rule": [f.end_rule for f in group],
            "friction_offset_n": _round([f.offset_n for f in group]),
            "residual_rms_n": _round([f.fit.residual_rms for f in group]),
            "points": [f.fit.points for f in group],
        }
        if rig_file.test == "bias_extension":
            record[branch]["kappa"] = _round([f.specimen.rig.kappa for f in group])
    test = rig_file.test.replace("_", "-")
    counts = ", ".join(f"{len(r['files'])} {b}" for b, r in record.items())
    doc = {
        "name": name,
        "description": rig_file.description or f"normalised from {test} tests ({counts})",
        "note": (f"Fitted by `uqdrape materials fit {rig_label}`: mean of the specimens' normalised shear force "
                 "N_s per branch, each cut to its valid range; the curve ends at the smallest valid end, "
                 "where locking is assumed." + "".join(f" Warning: {w}" for w in warnings)),
        "phi0_deg": rig_file.phi0_deg,
        "shear": shear,
    }
    if scatter:
        doc["scatter"] = scatter
    doc["sheartest"] = {
        "test": rig_file.test,
        "rig": rig_label,
        "force_convention": rig_file.force_convention,
        "force_unit": "N" if rig_file.force_convention == "crosshead" else "N/m",
        "normalisation": _NORMALISATION.get(rig_file.force_convention) or _NORMALISATION[rig_file.test],
        "fit_method": METHOD.format(knots=options["knots"]),
        **{key: options[key] for key in ("friction", "jump_deg", "max_angle_deg", "max_divergence_deg")},
        **record,
    }
    return CardFit(doc, fits, warnings)


def _round(values):
    """Numbers for the card: 7 significant digits (a test's precision is far coarser)."""
    return [float(f"{v:.7g}") for v in np.asarray(values, dtype=float)]
