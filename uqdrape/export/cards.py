"""Both yarn directions per element in the cards of three FE solvers.

A sheared woven or non-crimp ply is not orthotropic in one frame, so each flavour gives
each yarn its own frame, in a form the solver keeps as written:

- ``abaqus`` (``STEM-orientations.inp``, an include for a flat input): two coordinate
  ``*DISTRIBUTION``s and the ``*ORIENTATION``s using them, UQDRAPE_YARN1 (local 1 =
  yarn 1, local 2 towards yarn 2) and UQDRAPE_YARN2 (local 1 = yarn 2, local 2 = -yarn 1
  made orthogonal: the same local 3). Abaqus takes local 1 as given and orthogonalises
  only local 2, so each yarn survives as local 1 of its own orientation: use them as the
  orientations of two plies of half the ply thickness (``*SHELL SECTION, COMPOSITE``; the
  file shows the lines). The vectors are unit, in global axes, in the element's plane
  (the yarns turned onto it, ``uqdrape.export.elements``), so Abaqus's projection of
  local 1 onto a shell's surface leaves them and their angle, 90 deg - shear, as
  written. Every element of the mesh has its row; an unmapped one gets the default
  (yarn 1 = e1, yarn 2 = e2 of its element frame) and is listed in
  ``*ELSET, ELSET=UQDRAPE_UNMAPPED``; the distributions' default rows (global x and y)
  serve only elements the mesh does not have.
- ``lsdyna`` (``STEM-lsdyna.k``): the mesh as ``*NODE`` and ``*ELEMENT_SHELL_BETA`` in two
  superimposed layers sharing the nodes: part 1 = yarn 1 (element id = the label), part
  2 = yarn 2 (id = label + offset, the offset a power of ten above every label), each
  element's BETA the yarn angle (deg) in the element frame (AOPT = 0: from n1 -> n2).
  Give each part a ``*SECTION_SHELL`` of half the ply thickness and a unidirectional
  material with AOPT = 0. Unmapped elements of both layers are ``*SET_SHELL_LIST`` 1.
- ``nastran`` (``STEM-nastran.bdf``, bulk data, large-field format): the mesh as
  ``GRID*`` and ``CQUAD4*`` / ``CTRIA3*`` in the same two layers (PID 1 yarn 1, PID 2
  yarn 2), each element's material axis given by MCID: a ``CORD2R*`` per element and
  yarn (CID = the element id) whose x axis is the yarn turned onto the element plane and
  whose z axis is the element normal, so no element x-axis convention is involved.

Nodes of the LS-DYNA and Nastran meshes are numbered 1.. in the mesh file's point
order; higher-order cells are written as their corner (linear) elements.

Every flavour also carries, as comment lines of its own syntax (``**`` / ``$``) starting
``UQDRAPE-FIELDS``, one row per element: label, map_status, theta1_deg, theta2_deg (the
yarn angles in the element frame, ``uqdrape.export.elements``), shear_deg, area_ratio
(cos shear) and, for an ensemble, the P5/P50/P95 of each yarn angle over the drapes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._version import __version__

#: The flavours and the file each writes (a suffix of the stem).
FLAVOURS = {"abaqus": "-orientations.inp", "lsdyna": "-lsdyna.k", "nastran": "-nastran.bdf"}
#: Element labels per line of an Abaqus *ELSET.
PER_LINE = 16
#: Element ids per line of an LS-DYNA *SET_SHELL_LIST.
PER_SET_LINE = 8


@dataclass
class Cards:
    """What a flavour writes: element ``labels`` (M,), ``corners`` (M, 4) node indices (-1:
    none), mesh ``points`` (P, 3) mm, the element ``frame`` (e1, e2, e3), the element
    ``values`` (defaults applied, ``uqdrape.export.elements``) and the ``source`` named."""

    labels: np.ndarray
    corners: np.ndarray
    points: np.ndarray
    frame: tuple
    values: dict
    source: str


def field_columns(values: dict) -> list[str]:
    """The columns of the UQDRAPE-FIELDS table of ``values``."""
    cols = ["theta1", "theta2", "shear", "area_ratio"]
    cols += sorted(k for k in values if k.startswith(("theta1_q", "theta2_q")))
    return cols


def field_table(prefix: str, values: dict, labels: np.ndarray) -> list[str]:
    """The UQDRAPE-FIELDS comment lines (header and one row per element)."""
    cols = field_columns(values)
    names = ["label", "map_status"] + [c if c == "area_ratio" else c + "_deg" for c in cols]
    lines = [f"{prefix} UQDRAPE-FIELDS {','.join(names)}"]
    for k, label in enumerate(labels):
        row = [str(label), str(int(values["map_status"][k]))] + [repr(float(values[c][k])) for c in cols]
        lines.append(f"{prefix} {','.join(row)}")
    return lines


def layer_offset(labels: np.ndarray) -> int:
    """The id offset of the yarn-2 layer: the least power of ten above every label."""
    return 10 ** max(1, math.ceil(math.log10(int(labels.max()) + 1)))


#: The header lines on the single drape's fields, after the element frame's.
FIELD_NOTES = ("unmapped elements (map_status 1 off the net, 2 off the mould): theta1 = 0, theta2 = 90, shear 0",
               "area_ratio = cos(shear): an inextensible fabric's sheared area over its flat area (thickness at "
               "constant fibre volume x 1/area_ratio)")


def header(prefix: str, source: str, what: list[str], notes=FIELD_NOTES) -> list[str]:
    """The comment lines (``prefix``) opening a file: ``source``, the lines ``what``, the
    element frame and the ``notes``."""
    lines = [f"fibre orientations of {source}, written by uqdrape {__version__}", *what,
             ("element frame: e3 = element normal by node order, e1 = edge node 1 -> node 2 made orthogonal to e3, "
              "e2 = e3 x e1; angles from e1 about e3"), *notes]
    return [f"{prefix} {line}" for line in lines]


#: The distribution table of the yarn orientations (two coordinates a row), its name and lines.
ABAQUS_TABLE = "UQDRAPE_FIBRE_TABLE"
ABAQUS_TABLE_LINES = [f"*DISTRIBUTION TABLE, NAME={ABAQUS_TABLE}", "COORD3D, COORD3D"]


def abaqus_orientations(prefix: str, labels: np.ndarray, yarn1: np.ndarray, yarn2: np.ndarray) -> list[str]:
    """The ``*DISTRIBUTION`` lines (on ``ABAQUS_TABLE``) and ``*ORIENTATION`` lines
    ``PREFIX_YARN1_ORIENTATION`` (local 1 = ``yarn1`` (M, 3), local 2 towards ``yarn2``) and
    ``PREFIX_YARN2_ORIENTATION`` (local 1 = ``yarn2``, local 2 = -``yarn1``) of the elements
    ``labels`` (see the module doc)."""
    lines = []
    for name, a, b, default in ((f"{prefix}_YARN2", yarn2, -yarn1, ", 0.0, 1.0, 0.0, -1.0, 0.0, 0.0"),
                                (f"{prefix}_YARN1", yarn1, yarn2, ", 1.0, 0.0, 0.0, 0.0, 1.0, 0.0")):
        lines += [f"*DISTRIBUTION, NAME={name}, LOCATION=ELEMENT, TABLE={ABAQUS_TABLE}", default]
        lines += [", ".join([str(label)] + [repr(float(x)) for x in (*a[k], *b[k])]) for k, label in enumerate(labels)]
    for name in (f"{prefix}_YARN1", f"{prefix}_YARN2"):
        lines += [f"*ORIENTATION, NAME={name}_ORIENTATION, DEFINITION=COORDINATES, SYSTEM=RECTANGULAR", name]
    return lines


def elset(name: str, labels: np.ndarray) -> list[str]:
    """An Abaqus ``*ELSET`` of the element ``labels``."""
    return [f"*ELSET, ELSET={name}"] + [", ".join(map(str, labels[a:a + PER_LINE]))
                                        for a in range(0, labels.size, PER_LINE)]


def shell_set(sid: int, ids: np.ndarray) -> list[str]:
    """An LS-DYNA ``*SET_SHELL_LIST`` ``sid`` of the element ``ids``."""
    return ["*SET_SHELL_LIST", f"{sid:10d}"] + ["".join(f"{e:10d}" for e in ids[a:a + PER_SET_LINE])
                                                 for a in range(0, ids.size, PER_SET_LINE)]


def comment_list(prefix: str, ids: np.ndarray) -> list[str]:
    """The element ``ids`` as comment lines (``prefix``)."""
    return [f"{prefix} " + " ".join(map(str, ids[a:a + PER_LINE])) for a in range(0, ids.size, PER_LINE)]


def abaqus(tmp: Path, cards) -> None:
    """The Abaqus include (see the module doc)."""
    v, labels = cards.values, cards.labels
    lines = header("**", cards.source, [
        "element labels: those of an Abaqus input mesh, else 1-based positions in the mesh file",
        "two orientations, one per yarn; use each for a ply of half the ply thickness, e.g.",
        "*SHELL SECTION, ELSET=<preform>, COMPOSITE",
        "<t/2>, 3, <UD material>, UQDRAPE_YARN1_ORIENTATION",
        "<t/2>, 3, <UD material>, UQDRAPE_YARN2_ORIENTATION",
        "vectors: unit, global axes, in the element's plane; default rows (global x, y): elements not in this mesh"])
    lines += ABAQUS_TABLE_LINES + abaqus_orientations("UQDRAPE", labels, v["yarn1"], v["yarn2"])
    unmapped = labels[v["map_status"] != 0]
    if unmapped.size:
        lines.append(f"** {unmapped.size} elements not on the draped net: yarn 1 = e1, yarn 2 = e2 of their frame")
        lines += elset("UQDRAPE_UNMAPPED", unmapped)
    lines += field_table("**", v, labels)
    tmp.write_text("\n".join(lines) + "\n", encoding="ascii")


def lsdyna_nodes(points: np.ndarray) -> list[str]:
    """The ``*NODE`` lines of the mesh ``points`` (P, 3) mm, numbered 1.. in order."""
    return ["*NODE", "$#   nid               x               y               z"] + [
        f"{k + 1:8d}{x:16.9e}{y:16.9e}{z:16.9e}" for k, (x, y, z) in enumerate(points)]


def lsdyna(tmp: Path, cards) -> None:
    """The LS-DYNA keyword file (see the module doc)."""
    v, labels = cards.values, cards.labels
    offset = layer_offset(labels)
    lines = ["*KEYWORD"] + header("$", cards.source, [
        (f"two layers of *ELEMENT_SHELL_BETA sharing the nodes: part 1 = yarn 1 (eid = element label), part 2 = "
         f"yarn 2 (eid = label + {offset}); BETA = the yarn angle, deg, AOPT = 0"),
        ("give parts 1 and 2 a *SECTION_SHELL of half the ply thickness and a unidirectional material; "
         "nodes are 1-based positions in the mesh file")])
    lines += lsdyna_nodes(cards.points)
    lines += ["*ELEMENT_SHELL_BETA", "$#   eid     pid      n1      n2      n3      n4",
              "$#          thic1           thic2           thic3           thic4            beta"]
    for pid, shift, theta in ((1, 0, v["theta1"]), (2, offset, v["theta2"])):
        for k, label in enumerate(labels):
            n = cards.corners[k] + 1
            n4 = n[3] if n[3] > 0 else n[2]
            lines.append(f"{label + shift:8d}{pid:8d}{n[0]:8d}{n[1]:8d}{n[2]:8d}{n4:8d}")
            lines.append(f"{'':64s}{theta[k]:16.10f}")
    unmapped = labels[v["map_status"] != 0]
    if unmapped.size:
        ids = np.concatenate([unmapped, unmapped + offset])
        lines += [f"$ {unmapped.size} elements of each layer not on the draped net: BETA the default",
                  *shell_set(1, ids)]
    lines += field_table("$", v, labels) + ["*END"]
    tmp.write_text("\n".join(lines) + "\n", encoding="ascii")


def nastran_real(x: float) -> str:
    """``x`` in at most 16 characters as Nastran reads a real (exponent without E), with
    as many significant digits as fit."""
    x = float(x)
    if x == 0.0:
        return "0.0"
    for digits in range(15, 0, -1):
        mantissa, exponent = f"{x:.{digits}e}".split("e")
        text = f"{mantissa}{int(exponent):+d}"
        if len(text) <= 16:
            return text
    raise ValueError(f"{x!r} does not fit a Nastran large field")


def large(name: str, fields: list[str]) -> list[str]:
    """A large-field entry: ``name*`` and 4 fields of 16 characters a line, continuation
    lines starting ``*``."""
    lines = []
    for a in range(0, len(fields), 4):
        lines.append(f"{(name + '*') if a == 0 else '*':8s}" + "".join(f"{f:>16s}" for f in fields[a:a + 4]))
    return lines


def nastran_grids(points: np.ndarray) -> list[str]:
    """The ``GRID*`` entries of the mesh ``points`` (P, 3) mm, numbered 1.. in order."""
    return [line for k, p in enumerate(points)
            for line in large("GRID", [str(k + 1), "", *map(nastran_real, p)])]


def nastran(tmp: Path, cards) -> None:
    """The Nastran bulk data (see the module doc)."""
    v, labels = cards.values, cards.labels
    offset = layer_offset(labels)
    e3 = cards.frame[2]
    lines = header("$", cards.source, [
        (f"two layers sharing the grids: PID 1 = yarn 1 (EID = element label), PID 2 = yarn 2 (EID = label + "
         f"{offset}); material axis by MCID = EID, a CORD2R whose x axis is the yarn, z the element normal"),
        ("give PID 1 and 2 a PSHELL of half the ply thickness and a unidirectional material; "
         "grids are 1-based positions in the mesh file")])
    lines += nastran_grids(cards.points)
    for pid, shift, yarn in ((1, 0, v["yarn1"]), (2, offset, v["yarn2"])):
        for k, label in enumerate(labels):
            eid, n = int(label) + shift, [str(int(g) + 1) for g in cards.corners[k] if g >= 0]
            lines += large("CORD2R", [str(eid), "0", "0.0", "0.0", "0.0",
                                       *map(nastran_real, e3[k]), *map(nastran_real, yarn[k])])
            kind = "CQUAD4" if len(n) == 4 else "CTRIA3"
            lines += large(kind, [str(eid), str(pid), *n, str(eid)])
    unmapped = labels[v["map_status"] != 0]
    if unmapped.size:
        lines.append(f"$ {unmapped.size} elements of each layer not on the draped net (default axes):")
        lines += comment_list("$", unmapped)
    lines += field_table("$", v, labels)
    tmp.write_text("\n".join(lines) + "\n", encoding="ascii")


WRITERS = {"abaqus": abaqus, "lsdyna": lsdyna, "nastran": nastran}
