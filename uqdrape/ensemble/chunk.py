"""One chunk of an ensemble: one batched drape of some realisations, and its netCDF file.

A chunk Dataset is the solver's drape Dataset (``uqdrape.drape.drape``) with the global
realisation indices as the ``realization`` coordinate, every sampled input along ``realization``
(scalar factors are stored by ``drape`` itself; a random spacing adds the segment
lengths ``seg_i`` (realization, cell_i, j) and ``seg_j`` (realization, i, cell_j), mm;
a random zero angle is ``gamma0``), in the ensemble layout of ``uqdrape.schema``: a
leading length-1 dimension ``blankholder_force``, the chunk's force level (N), and the
force each drape was run with in ``applied_blankholder_force``.
"""

from __future__ import annotations

import errno
import functools
import json
import shutil
import threading
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # annotations only: xarray is imported where a Dataset is made or read
    import xarray as xr

from .. import files
from .. import geometry as _geometry
from ..drape import drape, drape_status
from ..drape.status import Status
from ..geometry.outline import contains, read_trim
from ..material.scatter import card_scatter, scattered
from ..schema import PLY, PLY_ANGLE, PLY_ATTR, REALIZATION, SOLVER_INPUTS, at_level
from ..study.spec import CARD
from .inputs import inputs_from_rows, sampled_inputs


#: One netCDF (HDF5) write or read at a time in a process: the HDF5 library under netCDF4
#: is not built thread-safe, and a dask worker with two threads writes two chunks at once
#: (a "NetCDF: HDF error", or the worker dying).
HDF5_LOCK = threading.RLock()


@functools.lru_cache(maxsize=8)
def _mould(kind: str, params: str, stamp):
    """A mould built once per process (``stamp``: the version of the file it reads), so a
    mesh tool is read and packed once, not for every chunk (a laminate's plies at their
    offsets: one mould each)."""
    return _geometry.build(kind, **json.loads(params))


def study_mould(study):
    """The study's mould from the process's cache (``_mould``), keyed by its parameters and,
    for a mould read from a file, the file's modification time and size."""
    g = study.geometry
    path = g.params.get("path")
    stat = Path(path).stat() if path is not None else None
    return _mould(g.kind, json.dumps(g.params, sort_keys=True), stat and (stat.st_mtime_ns, stat.st_size))


def drape_chunk(study, realizations, force: float, sample_rows=None) -> xr.Dataset:
    """The task every run drapes: realisations ``realizations`` of the study's sample, or
    the sample rows ``sample_rows`` (one per realisation), at force level ``force`` (N),
    in the ensemble layout (``uqdrape.schema.at_level``)."""
    r = np.asarray(realizations)
    if study.plies:
        return at_level(drape_laminate(study, r, force=force), force)
    inputs = sampled_inputs(study, r) if sample_rows is None else inputs_from_rows(study, sample_rows)
    return at_level(drape_inputs(study, r, inputs, force=force), force)


def ply_inputs(study, k: int, realizations, shared: dict | None = None) -> dict:
    """Solver inputs of ply ``k`` of a laminate for the given realisations: the ply's own
    draws (:meth:`Study.ply_study`), with the factors every ply shares (``shared``:
    ``sampled_inputs(study.shared, realizations)``) put in; a drawn rosette angle turns
    the ply by its difference from the nominal ``fabric.orientation_deg``."""
    r = np.asarray(realizations, dtype=np.int64)
    shared = sampled_inputs(study.shared, r) if shared is None else shared
    ply = study.ply_study(k)
    inputs = sampled_inputs(ply, r)
    for name, value in shared.items():
        if name == "orientation":
            own = inputs.get("orientation", np.full(r.size, ply.fabric.orientation_deg))
            inputs["orientation"] = own + (value - study.fabric.orientation_deg)
        else:
            inputs[name] = value
    return inputs


def drape_laminate(study, realizations, *, force=None) -> xr.Dataset:
    """Every ply of a laminate for the given realisations, each ply a member of one batched
    drape per card, spacing and offset from the tool (so a laminate costs what its plies cost): the solver's
    Dataset with a ``ply`` dimension before ``realization`` (``uqdrape.schema.PLY``), the
    ply names and ``ply_angle`` (deg from the rosette) as coordinates; an attribute whose
    value differs between plies (a ply's card, its spacing) becomes a coordinate along
    ``ply`` named ``ply_<attribute>`` (``uqdrape.schema.ply_dataset`` puts it back), and the
    laminate's own ``mould`` is the tool's (ply 0 lies on it). A drape in the batch is the
    one a single-ply study of ``study.ply_study(k)`` gives, bitwise, when no factor is shared."""
    import xarray as xr

    r = np.asarray(realizations, dtype=np.int64)
    shared = sampled_inputs(study.shared, r)
    parts, groups = {}, {}
    for k, ply in enumerate(study.plies):
        groups.setdefault((ply.material, ply.spacing_mm, study.ply_offset(k)), []).append(k)
    for members in groups.values():
        plies = [study.ply_study(k) for k in members]
        inputs = [ply_inputs(study, k, r, shared) for k in members]
        batch = {name: np.concatenate([_filled(ply, i, name, r.size, force) for ply, i in zip(plies, inputs)])
                 for name in set(SOLVER_INPUTS).union(*inputs)}
        ds = drape_inputs(plies[0], np.tile(r, len(members)), batch, force=force)
        for m, k in enumerate(members):
            part = ds.isel({REALIZATION: slice(m * r.size, (m + 1) * r.size)})
            parts[k] = part if study.plies[k].trim is None else trimmed(part, read_trim(study.plies[k].trim))
    parts = [parts[k] for k in range(len(study.plies))]
    ds = xr.concat(parts, dim=PLY, data_vars="all", coords="minimal", compat="override", join="override",
                   combine_attrs="drop_conflicts")
    differ = {f"{PLY_ATTR}{name}": (PLY, [p.attrs[name] for p in parts]) for name in parts[0].attrs
              if name not in ds.attrs}
    return ds.assign_coords({
        PLY: [p.name for p in study.plies],
        PLY_ANGLE: (PLY, [p.angle_deg for p in study.plies], {"units": "degree",
                                                                "long_name": "ply angle from the rosette"}),
        **differ}).assign_attrs(rosette_deg=study.fabric.orientation_deg,
                                **{name: parts[0].attrs[name] for name in ("mould", "geometry_json")})


def trimmed(ds: xr.Dataset, edge: np.ndarray) -> xr.Dataset:
    """A ply's drapes cut to its ``edge`` (K, 2 plan polyline, mm): each node whose plan
    position lies outside it gets status TRIMMED and NaN outputs, each cell with such a
    corner NaN (False where boolean); the inputs (gamma0, segments) and per-drape values
    stay as draped: the net was formed whole, then cut."""
    out = ~contains(edge, ds["x"].transpose(REALIZATION, "i", "j").values,
                    ds["y"].transpose(REALIZATION, "i", "j").values)
    cell = out[..., :-1, :-1] | out[..., 1:, :-1] | out[..., :-1, 1:] | out[..., 1:, 1:]
    ds = ds.copy()
    for name, var in ds.data_vars.items():
        sites = ("i", "j") if {"i", "j"} <= set(var.dims) else ("cell_i", "cell_j") \
            if {"cell_i", "cell_j"} <= set(var.dims) and name != "gamma0" else None
        if sites is None or name == "status":
            continue
        mask = (out if sites == ("i", "j") else cell).reshape(
            [ds.sizes[d] if d in (REALIZATION, *sites) else 1 for d in var.transpose(REALIZATION, *sites, ...).dims])
        values = var.transpose(REALIZATION, *sites, ...).values
        values = np.where(mask, False if values.dtype == bool else np.nan, values)
        ds[name] = var.transpose(REALIZATION, *sites, ...).copy(data=values).transpose(*var.dims)
    status = ds["status"].transpose(REALIZATION, "i", "j")
    ds["status"] = status.copy(data=np.where(out, int(Status.TRIMMED), status.values).astype(status.dtype))
    return ds


def _filled(ply, inputs: dict, name: str, R: int, force) -> np.ndarray:
    """Input ``name`` of one ply's ``inputs`` for a batch with other plies: as drawn, or the
    ply's fixed value where it does not draw it (nominal segments, zero gamma0)."""
    if name in inputs:
        return np.asarray(inputs[name], dtype=float)
    n, s = ply.solver.rings, ply.fabric.spacing_mm
    shapes = {"seg_i": (R, 2 * n, 2 * n + 1), "seg_j": (R, 2 * n + 1, 2 * n), "gamma0": (R, 2 * n, 2 * n)}
    if name in shapes:
        return np.full(shapes[name], 0.0 if name == "gamma0" else s)
    return np.full(R, ply.setting(name, force))


def drape_inputs(study, realizations, inputs: dict, *, force=None, surface=None, material=None) -> xr.Dataset:
    """One batched drape of ``realizations`` (global indices) with ``inputs`` from
    ``sampled_inputs`` / ``inputs_from_rows``; settings a factor does not vary are the
    study's fixed ones. ``force`` (N) must be one of the study's blank-holder force
    levels (None: the only level of a study without a sweep). Returns the solver's drape
    Dataset (the force per realisation). ``surface`` / ``material`` may be passed to reuse
    them (default: the study's mould from the process's cache, :func:`study_mould`, and
    its material loaded)."""
    r = np.asarray(realizations, dtype=np.int64)
    args, options = _drape_arguments(study, r, inputs, force, surface, material)
    ds = drape(*args, **options).assign_coords(realization=r)
    if CARD in inputs:
        ds[CARD] = (REALIZATION, np.asarray(inputs[CARD], dtype=float),
                    {"units": "1", "long_name": "card scatter score z: N_s = mean + z sd of the card's specimens"})
    if "seg_i" in inputs:
        ds["seg_i"] = ((REALIZATION, "cell_i", "j"), inputs["seg_i"],
                       {"units": "mm", "long_name": "fibre-1 segment length (flat blank)"})
        ds["seg_j"] = ((REALIZATION, "i", "cell_j"), inputs["seg_j"],
                       {"units": "mm", "long_name": "fibre-2 segment length (flat blank)"})
    return ds


def placement_status(study, realizations, inputs: dict, *, force=None) -> np.ndarray:
    """The node status (R, 2n + 1, 2n + 1) of :func:`drape_inputs` with the same arguments
    (``uqdrape.drape.drape_status``: the same solve, no Dataset)."""
    args, options = _drape_arguments(study, np.asarray(realizations, dtype=np.int64), inputs, force, None, None)
    return drape_status(*args, **options)


def _drape_arguments(study, r, inputs: dict, force, surface, material) -> tuple[tuple, dict]:
    """The arguments and options of the solver's ``drape`` for :func:`drape_inputs`."""
    levels = study.force_levels
    if (force is None and study.is_sweep) or (force is not None and float(force) not in levels):
        raise ValueError(f"force={force!r}: pass one of study {study.name!r}'s blank-holder levels {list(levels)} N")
    fabric, process, solver = study.fabric, study.process, study.solver
    settings = {name: study.setting(name, force) for name in SOLVER_INPUTS}
    unknown = sorted(set(inputs) - set(settings) - {"seg_i", "seg_j", "gamma0", CARD})
    if unknown:
        raise ValueError(f"inputs {unknown} are not solver inputs; valid: seg_i, seg_j, gamma0, {CARD}, "
                         f"{', '.join(settings)}")
    R = len(r)
    value = {name: np.broadcast_to(inputs.get(name, fixed), (R,)) for name, fixed in settings.items()}
    return (study_mould(study) if surface is None else surface, fabric.spacing_mm, solver.rings), dict(
        orientation=value["orientation"], pre_shear=value["pre_shear"], skew=value["skew"],
        crossover=np.stack([value["crossover_x"], value["crossover_y"]], axis=-1),
        seg_i=inputs.get("seg_i"), seg_j=inputs.get("seg_j"), gamma0=inputs.get("gamma0"),
        mode=solver.mode,
        material=_chunk_materials(fabric, material, inputs.get(CARD)),
        blankholder_force=value["blankholder_force"], friction=value["friction"],
        sectors=process.sectors, blankholder_model=process.blankholder_model,
        tolerance=solver.tolerance_deg, max_iterations=solver.max_iterations,
    )


def _chunk_materials(fabric, material, scores):
    """The material of a chunk: ``material`` (or the fabric's card, ``Fabric.card``), or
    with card scatter scores z one card per realisation (``uqdrape.material.scatter``)."""
    base = fabric.card() if material is None else material
    if scores is None:
        return base
    scatter = card_scatter(fabric.material)
    return [scattered(base, scatter, z) for z in np.asarray(scores, dtype=float)]


def write_atomic(ds: xr.Dataset, path: Path, encoding: dict | None = None) -> Path:
    """Write ``ds`` (with netCDF ``encoding``) to ``path`` via ``<path>.part`` in the same
    directory and a rename (uqdrape.files.write_atomic), so ``path`` exists only complete.
    A leftover ``.part`` (a killed writer) is overwritten, never read; a failed write
    removes its ``.part`` and raises OSError naming the path and the cause (a full disk is
    said so: netCDF itself only reports "HDF error")."""
    path = Path(path)
    return files.write_atomic(path, lambda part: write_netcdf(ds, part, encoding, target=path), keep_suffix=False)


def write_netcdf(ds: xr.Dataset, part: Path, encoding: dict | None = None, *, target: Path) -> None:
    """Write ``ds`` to the temporary file ``part`` of ``target`` (netCDF4, ``encoding``);
    a failure removes ``part`` and raises OSError naming ``target`` and the cause (a full
    disk said so: netCDF itself only reports "HDF error")."""
    try:
        with HDF5_LOCK:
            ds.to_netcdf(part, engine="netcdf4", encoding=encoding)
    except Exception as err:
        if isinstance(err, OSError) and err.errno is not None:  # the OS said what went wrong
            raise
        Path(part).unlink(missing_ok=True)  # first, so that the free space below is without it
        if shutil.disk_usage(Path(target).parent).free < ds.nbytes:
            raise OSError(errno.ENOSPC, "the disk is full", str(target)) from err
        raise OSError(errno.EIO, f"netCDF could not write it ({err})", str(target)) from err
