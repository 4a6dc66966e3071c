"""An LS-DYNA keyword mesh (``.k``, ``.key``, ``.dyn``), which meshio does not read.

Read: ``*NODE`` (NID, X, Y, Z) and the shell elements of ``*ELEMENT_SHELL`` (EID, PID,
N1..N4; N3 = N4 a triangle), with its options THICKNESS, BETA and MCID (one more card per
element) and OFFSET (another), each line in fixed columns (I8, 3 x E16 / 10 x I8) or
comma-separated free format; lines starting ``$`` are comments. ``*ELEMENT_SOLID`` and
``*ELEMENT_TSHELL`` cards are not read, but mark the mesh as a volume mesh (refused);
every other keyword is skipped. Element labels are the EIDs (``LABELS`` in cell data).
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

#: The file suffixes read as LS-DYNA keyword files.
SUFFIXES = (".k", ".key", ".dyn")
#: Cell data holding each element's EID.
LABELS = "lsdyna:eid"
#: The *ELEMENT_SHELL options read: THICKNESS, BETA and MCID share one more card per element, OFFSET adds one.
SHELL_OPTIONS = ("THICKNESS", "BETA", "MCID", "OFFSET")
#: Keywords of volume elements: not read, but the mesh is a volume mesh.
VOLUME = ("ELEMENT_SOLID", "ELEMENT_TSHELL")


def _fields(line: str, widths: list[int]) -> list[str]:
    """The fields of a free-format (comma-separated) or fixed-column ``line``."""
    if "," in line:
        return [f.strip() for f in line.split(",")]
    starts = np.cumsum([0] + widths)
    return [line[a:b].strip() for a, b in zip(starts[:-1], starts[1:])]


def read_keyword(path) -> meshio.Mesh:
    """The nodes and shell elements of the keyword file ``path`` (and an empty hexahedron
    block if it has volume elements); ValueError naming the file and line for a line
    that is not numbers where they belong."""
    path = Path(path)
    nodes, shells, volume, block, extra, skip = {}, {"quad": [], "triangle": []}, False, None, 0, 0
    for lineno, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        if line.startswith("$") or not line.strip():
            continue
        if line.startswith("*"):
            name = line[1:].strip().upper()
            volume |= name.startswith(VOLUME)
            block, options = (name, set()) if name == "NODE" else (None, set())
            if name.startswith("ELEMENT_SHELL"):
                block, options = "ELEMENT_SHELL", set(name.split("_")[2:])
                if not options <= set(SHELL_OPTIONS):
                    raise ValueError(f"{path}: line {lineno}: *{name} is not read (*ELEMENT_SHELL options read: "
                                     f"{', '.join(SHELL_OPTIONS)})")
            extra, skip = bool(options & {"THICKNESS", "BETA", "MCID"}) + ("OFFSET" in options), 0
        elif block is not None and skip:
            skip -= 1
        elif block is not None:
            try:
                if block == "NODE":
                    f = _fields(line, [8, 16, 16, 16])
                    nodes[int(f[0])] = [float(x or 0.0) for x in f[1:4]]
                else:
                    f = [int(x) for x in _fields(line, [8] * 6)]
                    kind = "triangle" if f[4] == f[5] else "quad"
                    shells[kind].append((f[0], f[2:5] if kind == "triangle" else f[2:6]))
                    skip = extra
            except (ValueError, IndexError):
                raise ValueError(f"{path}: line {lineno}: expected a *{block} line of numbers") from None
    index = {nid: k for k, nid in enumerate(nodes)}
    try:
        blocks = [(kind, np.array([[index[n] for n in c[1]] for c in rows])) for kind, rows in shells.items() if rows]
    except KeyError as err:
        raise ValueError(f"{path}: element node {err.args[0]} is not in *NODE") from None
    labels = [np.array([c[0] for c in rows]) for rows in shells.values() if rows]
    if volume:
        blocks.append(("hexahedron", np.zeros((0, 8), dtype=int)))
        labels.append(np.zeros(0, dtype=int))
    return meshio.Mesh(np.array(list(nodes.values()), dtype=float).reshape(-1, 3), blocks,
                       cell_data={LABELS: labels})
