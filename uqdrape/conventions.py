"""CF-1.8 encoding of the netCDF files uqdrape writes (drape files and ensemble chunks).

All CF rules live here, applied at write time by :func:`cf_encode` and undone where a
reader needs the drape Dataset's own layout by :func:`cf_decode`; the in-memory Dataset
and its numbers are unchanged unless ``float32`` is asked for.

- node variables name ``x y z`` in their ``coordinates`` attribute, so CF tools place them
- index coordinates carry ``long_name`` and ``units``; no coordinate has a ``_FillValue``
- ``flag_values`` have the variable's own type; booleans are bytes with
  ``flag_values = 0b, 1b`` and ``flag_meanings = "false true"``
- coordinate variables are numeric: a string-valued one (``arm``, ``quadrant``) is
  written as its position 0, 1, ... with the labels in ``<name>_label`` (a char
  auxiliary coordinate)
- global ``title``, ``history``, ``source`` (package and git version), ``date_created``
- optional: float variables stored as float32 with zlib (the 127-drape nose-cone
  ensemble: 9.8 MB instead of 27.6 MB; numbers rounded to float32, relative 6e-8)
- global attributes and variables an older uqdrape wrote under another name
  (:data:`RENAMED_ATTRS`, :data:`RENAMED_VARIABLES`) are read under their current name:
  the one place where old names are read
"""

from __future__ import annotations

import datetime
import functools
import subprocess
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # only in annotations: the CLI's --version does not load xarray
    import xarray as xr

from ._version import __version__

CONVENTIONS = "CF-1.8"
#: Node positions that place every (i, j) variable.
POSITIONS = ("x", "y", "z")
#: Suffix of the variable holding the labels of a string-valued coordinate.
LABEL = "_label"
#: Global attributes an older uqdrape wrote, by their current names (issue 35: "design"
#: is the blank-holder optimisation's word; a sensitivity run's rows are a sample matrix).
#: Written under the current names; :func:`cf_decode` reads either.
RENAMED_ATTRS = {"design_method": "sample_method", "design_base_samples": "sample_base_samples",
                 "design_evaluations": "sample_evaluations"}
#: Variables an older uqdrape wrote, by their current names (issue 35: a drape file kept the
#: force each drape saw as ``blankholder_force``, the name of an ensemble's level dimension;
#: it is ``uqdrape.schema.APPLIED_FORCE``). :func:`cf_decode` reads either.
RENAMED_VARIABLES = {"blankholder_force": "applied_blankholder_force"}
#: Attributes of the index coordinates a drape Dataset can have.
INDEX_ATTRS = {
    "realization": ("realisation index (global within the study)", "1"),
    "i": ("node index along fibre 1 (0 at the crossover)", "1"),
    "j": ("node index along fibre 2 (0 at the crossover)", "1"),
    "cell_i": ("cell centre index along fibre 1 (half-integer)", "1"),
    "cell_j": ("cell centre index along fibre 2 (half-integer)", "1"),
    "ring": ("generator-path step from the crossover", "1"),
    "arm": ("generator arm (direction from the crossover)", None),
    "quadrant": ("net quadrant (signs of i and j)", None),
}


@functools.cache
def git_version() -> str:
    """``git describe`` of the checkout uqdrape runs from, or "" outside a git checkout."""
    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty", "--tags"], cwd=Path(__file__).parent,
                             capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return ""
    return out.stdout.strip() if out.returncode == 0 else ""


def version_text() -> str:
    """``uqdrape 0.1.0`` plus ``(git <describe>)`` when run from a checkout."""
    git = git_version()
    return f"uqdrape {__version__}" + (f" (git {git})" if git else "")


def cf_encode(ds: xr.Dataset, *, title: str, history: str, float32: bool = False) -> tuple[xr.Dataset, dict]:
    """A copy of ``ds`` with CF attributes and the ``encoding`` to pass to ``to_netcdf``.

    ``title`` names the file's content, ``history`` the command that made it (a line
    stamped with the UTC time is added to any earlier history). ``float32`` stores
    float variables (not coordinates) as float32 with zlib compression.
    """
    out = ds.copy()
    now = datetime.datetime.now(datetime.UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")
    earlier = out.attrs.get("history")
    out.attrs.update(Conventions=CONVENTIONS, title=title, source=version_text(), date_created=now,
                     history=f"{now} {history}" + (f"\n{earlier}" if earlier else ""))
    for name, (long_name, units) in INDEX_ATTRS.items():
        if name in out.coords:
            out[name].attrs.setdefault("long_name", long_name)
            if units is not None:
                out[name].attrs.setdefault("units", units)
    for name in [c for c in out.dims if c in out.coords and out[c].dtype.kind in "USO"]:
        label = f"{name}{LABEL}"
        out[label] = (name, out[name].values.astype(str), {"long_name": out[name].attrs.get("long_name", name)})
        out[label].encoding["dtype"] = "S1"
        out = out.assign_coords({name: (name, np.arange(out.sizes[name], dtype=np.int32),
                                        {"long_name": f"position along {name} (labels: {label})", "units": "1"})})
    encoding = {name: {"_FillValue": None} for name in out.coords}
    place = all(p in out for p in POSITIONS)
    for name, var in out.data_vars.items():
        if var.dtype == bool:
            var.attrs.update(flag_values=np.array([0, 1], np.int8), flag_meanings="false true")
        elif "flag_values" in var.attrs:
            var.attrs["flag_values"] = np.asarray(var.attrs["flag_values"]).astype(var.dtype)
        aux = [p for p in POSITIONS if place and name not in POSITIONS and {"i", "j"} <= set(var.dims)]
        aux += [f"{d}{LABEL}" for d in var.dims if f"{d}{LABEL}" in out and name != f"{d}{LABEL}"]
        if aux:
            var.encoding["coordinates"] = " ".join(aux)  # xarray writes it as the attribute
        if float32 and var.dtype.kind == "f":
            encoding[name] = {"dtype": "float32", "zlib": True, "complevel": 4}
    return out, encoding


def cf_decode(ds: xr.Dataset) -> xr.Dataset:
    """The Dataset layout of ``uqdrape.drape``: node positions that a CF-aware reader made
    coordinates (from the ``coordinates`` attributes) become data variables again, and
    string coordinates get their labels back; attributes an older uqdrape wrote get their
    current names (:data:`RENAMED_ATTRS`; where a file holds both, the current one), and so
    do data variables (:data:`RENAMED_VARIABLES`; an ensemble's level coordinate is no data
    variable)."""
    ds = ds.reset_coords([p for p in POSITIONS if p in ds.coords])
    ds = ds.rename_vars({k: v for k, v in RENAMED_VARIABLES.items() if k in ds.data_vars and v not in ds})
    if RENAMED_ATTRS.keys() & ds.attrs.keys():
        ds.attrs = {RENAMED_ATTRS.get(k, k): v for k, v in ds.attrs.items()
                    if not (k in RENAMED_ATTRS and RENAMED_ATTRS[k] in ds.attrs)}
    for label in [v for v in ds.variables if str(v).endswith(LABEL) and str(v)[:-len(LABEL)] in ds.dims]:
        name = label[:-len(LABEL)]
        attrs = {k: v for k, v in ds[name].attrs.items() if k not in ("long_name", "units")}
        ds = ds.drop_vars(label).assign_coords({name: (name, ds[label].values.astype(str), attrs)})
    return ds
