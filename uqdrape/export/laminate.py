"""The structural FE handoff of a laminate: every ply's yarn angles on the user's shell mesh.

A laminate ensemble has the dims (``blankholder_force``, ``ply``, ``realization``, i, j):
each ply a drape of the ply book over one tool (``uqdrape.schema.PLY``). Every drape of
every ply is mapped onto the elements of a shell mesh exactly as a single drape is
(``uqdrape.export.fe``: centroid onto the mould, located in the draped net, the fibre
directions interpolated barycentrically and opened to 90 deg - shear, turned onto the
element plane), giving both yarn angles of each element, ply and realisation in the
element frame (``uqdrape.export.elements``: e1 along the edge node 1 -> node 2, about the
element normal e3). An element a drape's net does not reach has no angle (NaN) in that
drape; a yarn is a line, so every angle is taken within +-90 deg of the nominal.

Error of the mapping. Against a net draped at a much finer spacing, the element yarn
angles of a net at spacing s err by O(s^2): the drape's chords, the central-difference
fibre tangents (``directions``) and the linear interpolation are each second order
(``tests/test_export_laminate.py`` observes order 2 on a hemisphere).

Written per force level (``STEM[-LEVEL]``; the level's label as ``uqdrape export``'s):

- the nominal layup ``-laminate.inp`` / ``.k`` / ``.bdf``: per element and ply the median
  of each yarn angle over the realisations that reach it (about their axial mean);
- ``realizations`` = N Monte Carlo decks ``-rNNNN-laminate.*``, the same files with the
  angles of the ensemble's first N realisations (NNNN its realisation index);
- ``-laminate.nc`` (CF-1.8): the samples ``yarn_angle`` (realization, ply, yarn, element;
  a ``yarn`` dimension, as a woven ply's two yarns scatter apart when it shears), the
  nominal, the fraction of realisations reaching each element, and their Karhunen-Loeve
  (PCA) reduction: the SVD of the centred samples over the (ply, yarn, element) entries
  that every realisation reaches (an entry some drape misses has no sample to centre),
  the fewest leading modes holding the fraction ``variance`` of the total variance, with
  their unit mode shapes, eigenvalues (deg^2), variance fractions and the samples'
  scores (deg); samples = mean + scores x modes, to within the variance left out.

The samples are held in memory: P x 2 x R x M floats (4 plies, 1000 drapes, 10^5
elements: 6.4 GB), and each drape is mapped in turn.

Decisions, per solver (each ply a woven or non-crimp fabric: its two yarns are two
unidirectional layers of half the ply thickness, yarn 1 first, as ``cards`` does):

- Abaqus: one ``*SHELL SECTION, COMPOSITE`` whose layers name ``*ORIENTATION``s defined by
  element ``*DISTRIBUTION``s (``cards.abaqus_orientations``, one pair per ply, ``PK`` the
  ply's position 1..P): Abaqus keeps a distribution's local 1 per element, the only way
  it takes per-element angles in one composite section. Material ``UQDRAPE_PK_MATERIAL``.
- LS-DYNA: ``*ELEMENT_SHELL_COMPOSITE``, which carries each element's own material,
  thickness and angle B per layer (``*PART_COMPOSITE`` has one angle per part, and two
  layers of ``*ELEMENT_SHELL_BETA`` would not stack through the thickness); B is from
  the element's n1 -> n2 edge: give the materials (MID = K) AOPT = 0 and part 1 a
  ``*SECTION_SHELL``. Its fields are 10 characters: B to 1e-5 deg.
- Nastran: a ``PCOMP`` per element (PID = element id; a PCOMP's THETA is per property, so
  per-element angles need per-element properties), its THETA from the material x axis
  that ``MCID`` sets: a ``CORD2R`` per element (CID = element id) whose x axis is e1 and
  z axis e3, so no element x-axis convention is involved. MID = K.

The cards follow each solver's manual; no deck was run through a solver here (the tests
read them back with parsers of their own).

Layers run from the tool outwards: ply 1 (the first in the ply book, on the tool) at the
bottom of an element whose normal e3 points away from the tool, at the top of one whose
e3 points into it (Abaqus: the second section, ``UQDRAPE_LAMINATE_FLIPPED``). The shell
reference surface is the solvers' default, the mid-surface: offset it if the mesh is the
tool face. Elements a ply's net does not reach (in the nominal: in no realisation) get
that ply's default angles 0 and 90 deg and are listed per ply (Abaqus
``*ELSET UQDRAPE_PK_UNMAPPED``, LS-DYNA ``*SET_SHELL_LIST`` K, Nastran comment lines).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
import xarray as xr

from ..files import write_all
from ..schema import FORCE, PLY, PLY_ANGLE, REALIZATION, ply_dataset
from .cards import (ABAQUS_TABLE_LINES, abaqus_orientations, comment_list, elset, header, large, lsdyna_nodes,
                    nastran_grids, nastran_real, shell_set)
from .elements import DEFAULT_THETA, axial_mean, axial_quantiles
from .fe import MeshOnMould, check_flavours, drape_angles, mesh_on_mould, tolerance_of
from .result import netcdf_file, surface_of

#: The file each flavour writes (a suffix of the stem).
LAMINATE = {"abaqus": "-laminate.inp", "lsdyna": "-laminate.k", "nastran": "-laminate.bdf"}
#: The two yarns of a ply: 1 along fibre 1 (the ply's nominal angle), 2 along fibre 2.
YARNS = (1, 2)


def karhunen_loeve(samples: np.ndarray, variance: float) -> dict:
    """The leading modes of ``samples`` (R, F): the fewest holding ``variance`` of the total
    variance. Returns mean (F,), modes (K, F) orthonormal, eigenvalues (K,) (the samples'
    covariance's, units of samples squared), fraction (K,) of the total each holds, scores
    (R, K) and the total variance."""
    mean = samples.mean(axis=0)
    _, sv, vt = np.linalg.svd(samples - mean, full_matrices=False)
    eigenvalues = sv ** 2 / max(len(samples) - 1, 1)
    total = eigenvalues.sum()
    if total > 0:
        fraction = eigenvalues / total
        keep = min(int(np.searchsorted(np.cumsum(fraction), variance * (1 - 1e-12))) + 1, len(fraction))
    else:  # all samples alike: the mean is the whole of them
        fraction, keep = np.zeros_like(eigenvalues), 0
    modes = vt[:keep]
    return {"mean": mean, "modes": modes, "eigenvalues": eigenvalues[:keep], "fraction": fraction[:keep],
            "scores": (samples - mean) @ modes.T, "total": total}


@dataclass
class Layup:
    """What a composite writer writes: the mesh ``on`` the mould (``fe.MeshOnMould``), the
    ``plies`` (names, P), ``thickness`` (P,) mm, yarn angles ``theta`` (P, 2, M) deg in the
    element frame (defaults where not ``reached``), ``reached`` (P, M), ``flipped`` (M,):
    elements whose normal points into the tool, and the ``source`` named."""

    on: MeshOnMould
    plies: list
    thickness: np.ndarray
    theta: np.ndarray
    reached: np.ndarray
    flipped: np.ndarray
    source: str

    def layers(self, k: int):
        """(ply position, yarn, thickness mm, angle deg) of element ``k``'s layers from its
        bottom (the side opposite its normal) up."""
        rows = [(p, y, 0.5 * self.thickness[p], self.theta[p, y, k])
                for p in range(len(self.plies)) for y in range(2)]
        return rows[::-1] if self.flipped[k] else rows

    def lines(self, prefix: str, what: list[str]) -> list[str]:
        """The header comment lines, naming each ply's position, name and thickness."""
        plies = [f"ply P{p + 1} = {name!r}: {t:g} mm, yarns 1 and 2 {0.5 * t:g} mm each"
                 for p, (name, t) in enumerate(zip(self.plies, self.thickness))]
        return header(prefix, self.source, [*what, *plies], notes=(
            "elements a ply's net does not reach: its yarn angles 0 and 90 deg, listed per ply at the end",
            "layers from the tool outwards: ply P1 first from the bottom where e3 points off the tool, else last"))

    def unmapped(self, p: int) -> np.ndarray:
        """Labels of the elements ply ``p``'s net does not reach."""
        return self.on.labels[~self.reached[p]]


def abaqus(tmp: Path, layup: Layup) -> None:
    """The Abaqus include of ``layup`` (see the module doc)."""
    on = layup.on
    e1, e2, _ = on.frame
    lines = layup.lines("**", ["a composite section per element normal sense; per ply two orientations, one a "
                               "yarn, from element distributions", "materials UQDRAPE_PK_MATERIAL: map them"])
    lines += ABAQUS_TABLE_LINES
    for p in range(len(layup.plies)):
        yarn1, yarn2 = (np.cos(np.radians(t))[:, None] * e1 + np.sin(np.radians(t))[:, None] * e2
                        for t in layup.theta[p])
        lines += abaqus_orientations(f"UQDRAPE_P{p + 1}", on.labels, yarn1, yarn2)
    for name, which in (("UQDRAPE_LAMINATE", ~layup.flipped), ("UQDRAPE_LAMINATE_FLIPPED", layup.flipped)):
        if which.any():
            lines += elset(name, on.labels[which])
            lines.append(f"*SHELL SECTION, ELSET={name}, COMPOSITE")
            lines += [f"{float(t)!r}, 3, UQDRAPE_P{p + 1}_MATERIAL, UQDRAPE_P{p + 1}_YARN{y + 1}_ORIENTATION, "
                      f"P{p + 1}_YARN{y + 1}" for p, y, t, _ in layup.layers(int(np.argmax(which)))]
    for p in range(len(layup.plies)):
        if layup.unmapped(p).size:
            lines += elset(f"UQDRAPE_P{p + 1}_UNMAPPED", layup.unmapped(p))
    tmp.write_text("\n".join(lines) + "\n", encoding="ascii")


def lsdyna(tmp: Path, layup: Layup) -> None:
    """The LS-DYNA keyword file of ``layup`` (see the module doc)."""
    on = layup.on
    lines = ["*KEYWORD"] + layup.lines("$", [
        "*ELEMENT_SHELL_COMPOSITE: per layer MID = ply position K, THICK (mm), B = yarn angle (deg) from n1 -> n2",
        "give part 1 a *SECTION_SHELL and materials 1..P with AOPT = 0; nodes: 1-based positions in the mesh file"])
    lines += lsdyna_nodes(on.mesh.points)
    lines += ["*ELEMENT_SHELL_COMPOSITE", "$#   eid     pid      n1      n2      n3      n4",
              "$#    mid1    thick1        b1              mid2    thick2        b2"]
    for k, label in enumerate(on.labels):
        n = on.corners[k] + 1
        lines.append(f"{label:8d}{1:8d}{n[0]:8d}{n[1]:8d}{n[2]:8d}{n[3] if n[3] > 0 else n[2]:8d}")
        cells = [f"{p + 1:10d}{t:10.6f}{b:10.5f}{'':10s}" for p, _, t, b in layup.layers(k)]
        lines += ["".join(cells[a:a + 2]).rstrip() for a in range(0, len(cells), 2)]
    for p in range(len(layup.plies)):
        ids = layup.unmapped(p)
        if ids.size:
            lines += [f"$ ply P{p + 1}: {ids.size} elements not on its draped net", *shell_set(p + 1, ids)]
    tmp.write_text("\n".join(lines + ["*END"]) + "\n", encoding="ascii")


def nastran(tmp: Path, layup: Layup) -> None:
    """The Nastran bulk data of ``layup`` (see the module doc)."""
    on = layup.on
    e1, _, e3 = on.frame
    lines = layup.lines("$", [
        "per element: CORD2R (CID = EID, x = e1, z = e3), PCOMP (PID = EID; MID = ply position K, T mm, THETA deg)",
        "and the element with MCID = EID; grids: 1-based positions in the mesh file"])
    lines += nastran_grids(on.mesh.points)
    for k, label in enumerate(on.labels):
        eid, n = str(label), [str(g + 1) for g in on.corners[k] if g >= 0]
        lines += large("CORD2R", [eid, "0", "0.0", "0.0", "0.0", *map(nastran_real, e3[k]), *map(nastran_real, e1[k])])
        plies = [f for p, _, t, b in layup.layers(k) for f in (str(p + 1), nastran_real(t), nastran_real(b), "")]
        lines += large("PCOMP", [eid, "", "", "", "", "", "", "", *plies])
        lines += large("CQUAD4" if len(n) == 4 else "CTRIA3", [eid, eid, *n, eid])
    for p in range(len(layup.plies)):
        ids = layup.unmapped(p)
        if ids.size:
            lines.append(f"$ ply P{p + 1}: {ids.size} elements not on its draped net (THETA 0 and 90):")
            lines += comment_list("$", ids)
    tmp.write_text("\n".join(lines) + "\n", encoding="ascii")


WRITERS = {"abaqus": abaqus, "lsdyna": lsdyna, "nastran": nastran}


def _samples(level: xr.Dataset, surface, on, tolerance_mm: float | None) -> np.ndarray:
    """Yarn angles (P, 2, R, M) deg of every drape of every ply of ``level``, each ply mapped
    with ``tolerance_mm`` (default its own spacing). A ply on the tool's offset surface
    (``thickness_mm`` below it) is mapped at the elements' foot points moved out along the
    tool's normal by its offset: the point of its own surface over the element."""
    out = []
    for name in level[PLY].values:
        ply = ply_dataset(level, name)
        own = surface_of(ply)
        xy, dist, reached = on.foot
        foot = (xy + (own.offset_mm - surface.offset_mm) * on.normal[:, :xy.shape[1]], dist, reached)
        angles = drape_angles(ply, own, foot, tolerance_of(ply, tolerance_mm), on.solver_frame)
        out.append([angles["theta1"], angles["theta2"]])
    return np.array(out)


def _statistics(level: xr.Dataset, labels: np.ndarray, samples: np.ndarray, variance: float):
    """The netCDF Dataset of the module doc, and the nominal angles (P, 2, M) deg."""
    P, _, R, M = samples.shape
    nominal = np.array([[axial_quantiles(s, axial_mean(s), (0.5,))[0] for s in ply] for ply in samples])
    samples = nominal[:, :, None] + (samples - nominal[:, :, None] + 90.0) % 180.0 - 90.0
    X = samples.transpose(2, 0, 1, 3).reshape(R, -1)
    every = np.isfinite(X).all(axis=0)
    kl = karhunen_loeve(X[:, every], variance)
    K = len(kl["eigenvalues"])

    def spread(values, lead):  # the reduced entries back on (..., ply, yarn, element), NaN elsewhere
        out = np.full((*lead, P * 2 * M), np.nan)
        out[..., every] = values
        return out.reshape(*lead, P, 2, M)

    deg = {"units": "degree"}
    grid = ("ply", "yarn", "element")
    ds = xr.Dataset(
        {"yarn_angle": ((REALIZATION, *grid), samples.transpose(2, 0, 1, 3),
                        {**deg, "long_name": "yarn angle in the element frame (from e1 about e3)"}),
         "nominal_yarn_angle": (grid, nominal, {**deg, "long_name": "median yarn angle over the realisations"}),
         "p_reached": (("ply", "element"), np.isfinite(samples[:, 0]).mean(axis=1),
                       {"units": "1", "long_name": "fraction of the realisations whose net reaches the element"}),
         "mean_yarn_angle": (grid, spread(kl["mean"], ()),
                             {**deg, "long_name": "mean yarn angle (entries every realisation reaches)"}),
         "mode_shape": (("mode", *grid), spread(kl["modes"], (K,)),
                        {"units": "1", "long_name": "Karhunen-Loeve mode shape (unit norm)"}),
         "eigenvalue": ("mode", kl["eigenvalues"], {"units": "degree^2", "long_name": "variance of the mode"}),
         "variance_fraction": ("mode", kl["fraction"], {"units": "1", "long_name": "fraction of the total variance"}),
         "score": ((REALIZATION, "mode"), kl["scores"], {**deg, "long_name": "the realisation's mode coefficient"})},
        coords={REALIZATION: level[REALIZATION].values, PLY: level[PLY].values,
                PLY_ANGLE: (PLY, level[PLY_ANGLE].values,
                            {**deg, "long_name": "nominal fibre-1 angle from the rosette"}),
                "yarn": ("yarn", np.array(YARNS, np.int32),
                         {"units": "1", "long_name": "yarn (1: fibre 1, 2: fibre 2)"}),
                "element": ("element", labels.astype(np.int64), {"units": "1", "long_name": "element label"}),
                "mode": ("mode", np.arange(1, K + 1, dtype=np.int32), {"units": "1", "long_name": "mode number"})},
        attrs={"variance_target": variance, "variance_retained": float(kl["fraction"].sum()),
               "total_variance_deg2": float(kl["total"]), "rosette_deg": float(level.attrs.get("rosette_deg", 0.0)),
               "mould": level.attrs.get("mould", "")})
    ds[PLY].attrs["long_name"] = "ply (stacking order, the first on the tool)"
    return ds, nominal


def laminate_files(ds: xr.Dataset, mesh_path, stem, *, flavours=("abaqus",), thickness_mm=1.0,
                   realizations: int = 0, variance: float = 0.99, tolerance_mm: float | None = None,
                   history: str = "uqdrape.export.laminate"):
    """Writers (for ``write_all``) of the laminate handoff of the module doc.

    Parameters
    ----------
    ds : xarray.Dataset
        A laminate ensemble: dims (blankholder_force, ply, realization, i, j), coordinates
        ``ply`` (names) and ``ply_angle`` (deg).
    mesh_path : path
        The shell mesh (any format meshio reads: Abaqus .inp, Nastran .bdf, LS-DYNA .k,
        ...; triangles and quads, mm, in the tool's axes).
    stem : path
        Output path stem; files are ``STEM[-LEVEL]-laminate.*`` and ``-rNNNN-laminate.*``.
    flavours : sequence of str
        Any of "abaqus", "lsdyna", "nastran".
    thickness_mm : float or sequence of float
        Cured ply thickness (mm, > 0): one for every ply, or one per ply.
    realizations : int
        Number N (0 .. R) of Monte Carlo decks per flavour: the first N realisations.
    variance : float
        Fraction (0, 1] of the yarn angles' total variance the kept modes hold.
    tolerance_mm : float, optional
        How far (mm) from the mould an element may lie; default each ply's fibre spacing
        (a mesh whose median element lies farther than the largest is refused).
    history : str
        The command that made the files, for the netCDF's ``history``.

    Returns
    -------
    dict
        Target path -> writer.
    """
    missing = [d for d in (FORCE, PLY, REALIZATION, "i", "j") if d not in ds.dims]
    if missing:
        raise ValueError(f"ds: no {', '.join(map(repr, missing))} dimension (dims {tuple(ds.dims)}); a laminate "
                         f"ensemble has ({FORCE}, {PLY}, {REALIZATION}, i, j)")
    check_flavours(flavours)
    plies = [str(p) for p in ds[PLY].values]
    try:
        thickness = np.broadcast_to(np.asarray(thickness_mm, dtype=float), (len(plies),))
    except ValueError:
        raise ValueError(f"thickness_mm: one value or one per ply ({len(plies)}), got {thickness_mm!r}") from None
    if not (np.isfinite(thickness) & (thickness > 0)).all():
        raise ValueError(f"thickness_mm: a ply thickness must be > 0 mm, got {thickness_mm!r}")
    R = ds.sizes[REALIZATION]
    if not (isinstance(realizations, (int, np.integer)) and 0 <= realizations <= R):
        raise ValueError(f"realizations: a number of decks 0 .. {R} (the ensemble's), got {realizations!r}")
    if not 0 < variance <= 1:
        raise ValueError(f"variance: a fraction in (0, 1], got {variance!r}")
    stem = Path(stem)
    surface = surface_of(ds)
    tol = max(tolerance_of(ply_dataset(ds, name), tolerance_mm) for name in ds[PLY].values)
    on = mesh_on_mould(mesh_path, surface, tol)
    flipped = np.einsum("ij,ij->i", on.solver_frame[2], on.normal) < 0
    ds = ds.transpose(FORCE, PLY, REALIZATION, ...)
    writers = {}
    for force in ds[FORCE].values:
        level = ds.sel({FORCE: force})
        label = f"{float(force):g}N" if ds.sizes[FORCE] > 1 else ""
        base = f"{stem.name}-{label}" if label else stem.name
        samples = _samples(level, surface, on, tolerance_mm)
        statistics, nominal = _statistics(level, on.labels, samples, variance)
        writers.update(netcdf_file(statistics, stem.with_name(f"{base}-laminate.nc"), history))
        source = f"{ds.attrs.get('mould', 'a laminate')}{' at ' + label if label else ''}"
        decks = [("", nominal, f"the median over {R} realisations")]
        width = len(str(int(level[REALIZATION].max())))
        decks += [(f"-r{int(level[REALIZATION][r]):0{max(4, width)}d}", samples[:, :, r],
                   f"realisation {int(level[REALIZATION][r])}") for r in range(realizations)]
        for suffix, theta, what in decks:
            reached = np.isfinite(theta[:, 0])
            default = np.array(DEFAULT_THETA)[None, :, None]
            layup = Layup(on, plies, thickness, np.where(np.isfinite(theta), theta, default), reached, flipped,
                          f"{source}, {what}")
            for flavour in dict.fromkeys(flavours):
                writers[stem.with_name(base + suffix + LAMINATE[flavour])] = partial(WRITERS[flavour], layup=layup)
    return writers


def export_laminate(ds: xr.Dataset, mesh_path, stem, **options) -> list[Path]:
    """Write the files of :func:`laminate_files` (same arguments), all or none; returns their paths."""
    return write_all(laminate_files(ds, mesh_path, stem, **options))
