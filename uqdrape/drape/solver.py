"""``drape``: a batch of pin-jointed-net drapes over one mould, as an xarray Dataset."""

from __future__ import annotations

import functools
import json
import multiprocessing
import numbers
import threading
from typing import TYPE_CHECKING

import numba
import numpy as np

if TYPE_CHECKING:  # annotations only: xarray is imported where a Dataset is made or read
    import xarray as xr

from .._version import __version__
from .._jit import compiled, on_threads
from ..errors import ParameterError
from ..schema import MODES, QUADRANTS, REALIZATION, SOLVER_INPUTS
from .energy import BlankHolder
from .kernels import net_node_mean, net_shear
from .net import EnergyRings, NetProblem, build_geodesic
from .ring import boundary_blankholder, drape_ring, geodesic_block
from .status import Status

#: Realisations solved and post-processed together per block (the solver is compiled per
#: realisation; the block bounds the memory of the Dataset's temporaries).
BLOCK = 1024


#: Seconds numba takes to compile each mode's kernels, once per cache (``uqdrape drape``, 30
#: rings on the hemisphere, 2-core development machine: geodesic 22.6 s with an empty cache
#: against 8.2 s with a full one, energy 41.8 against 8.3 s).
COMPILE_S = {"geodesic": 15, "energy": 35}


def compile_pending(mode: str) -> bool:
    """Whether a drape in ``mode`` must compile kernels before its first ring: one that it
    calls from Python is neither compiled in this process nor in the disk cache."""
    ring = drape_ring if mode == "energy" else geodesic_block
    return not all(compiled(k) for k in (ring, net_shear, net_node_mean, boundary_blankholder))


def _per_realisation(name, value, tail, R):
    """Broadcast ``value`` to (R, *tail) float64, or raise naming the argument."""
    a = np.asarray(value, dtype=float)
    if a.shape == tail:
        a = np.broadcast_to(a, (R, *tail))
    elif a.shape[1:] != tail or a.shape[0] != R:
        raise ValueError(f"{name} has shape {a.shape}; expected {tail} or {(R, *tail)} for R = {R} realisations")
    return np.array(a)


def _segments(name, value, spacing, tail, R):
    """Segment lengths (R, *tail) mm: the nominal ``spacing`` everywhere for None, else
    ``value`` broadcast, checked finite and positive (raises naming the argument)."""
    if value is None:
        return np.full((R, *tail), float(spacing))
    a = _per_realisation(name, value, tail, R)
    if not (np.isfinite(a).all() and (a > 0).all()):
        raise ValueError(f"{name}: every segment length must be finite and > 0 mm")
    return a


def _batch_size(**arrays):
    """Number of realisations implied by the leading axes of the batched arguments."""
    sizes = {name: np.shape(v)[0] for name, (v, ndim) in arrays.items()
             if v is not None and np.ndim(v) == ndim + 1}
    distinct = set(sizes.values())
    if len(distinct) > 1:
        raise ValueError(f"batched arguments disagree on the number of realisations: {sizes}")
    return distinct.pop() if distinct else 1


def default_threads():
    """Threads sharing a batch: numba's thread count (one per core unless the environment
    sets NUMBA_NUM_THREADS) for a call from the main thread of the main process, else 1,
    because ensemble workers (one process per core) and the threads of a thread pool
    already share the cores among themselves."""
    if multiprocessing.parent_process() is None and threading.current_thread() is threading.main_thread():
        return numba.config.NUMBA_NUM_THREADS
    return 1


def drape(surface, spacing, rings, *, orientation=0.0, pre_shear=0.0, skew=0.0,
          crossover=(0.0, 0.0), seg_i=None, seg_j=None, gamma0=None, mode="geodesic",
          material=None, blankholder_force=0.0, friction=0.2, sectors=None,
          blankholder_model="slip", tolerance=1e-3, max_iterations=30, max_turn=10.0, factors=None,
          progress=None, threads=None) -> xr.Dataset:
    """Drape a batch of pin-jointed nets over ``surface``; one Python loop for the batch.

    Arguments that may differ per realisation take a scalar (or base shape) or an array
    with a leading realisation axis of length R:

    spacing            nominal fibre spacing s (mm) of the flat blank, scalar
    rings              n: the net has nodes (i, j), |i|, |j| <= n
    orientation        plan angle (deg) of fibre 1 (+i) from the x axis at the crossover
    pre_shear          shear (deg) of the flat blank: fibre 2 at orientation + 90 - pre_shear
    skew               extra angle (deg) closed between the generator paths at the crossover,
                       split equally between them; the flat blank is unchanged (thesis Fig 5.5)
    crossover          plan position (mm) of node (0, 0), the first point of contact, (2,) or (R, 2)
    seg_i, seg_j       fibre-1 / fibre-2 segment lengths (mm), (2n, 2n+1) / (2n+1, 2n); default s
    gamma0             zero-energy shear angle per cell (deg), (2n, 2n); default 0
    mode               "geodesic" (straightest arms) or "energy" (arms steered per step)
    material           a ``uqdrape.material.Material``, or one per realisation (a sequence
                       of R, e.g. a card's specimen scatter sampled per drape) sharing
                       locking angles, phi0 and bending stiffness; needed for mode="energy"
    blankholder_force  total blank-holder force F_BH (N), stored as ``applied_blankholder_force``
                       (``uqdrape.schema.APPLIED_FORCE``); friction: mu_BH (-)
    sectors            relative blank-holder force per equal angular sector (None: uniform)
    blankholder_model  "slip" (friction on the held fabric's whole plan slip, the default) or
                       "radial" (thesis Eq 5.1-5.5: radial draw-in only); see ``BlankHolder``
    tolerance          minimiser tolerance on the turn angles (deg)
    max_iterations     minimiser iterations per step; max_turn: bound on a turn (deg)
    factors            dict of extra per-realisation values stored along ``realization``
    progress           None (silent), or a callable given the number of rings placed so far in
                       the current block of realisations (BLOCK of them): after each ring of an
                       energy drape, once with ``rings`` when a geodesic block is done
    threads            threads sharing a batch's realisations (None: ``default_threads()``);
                       the drapes are the same whatever the count

    Nodes that cannot be placed are NaN with a ``status`` code (``Status``); the call
    does not raise for them. Impossible arguments raise ValueError naming the argument.
    """
    import xarray as xr

    blocks = [_dataset(prob, *solved, mode, stored, gamma0, threads)
              for prob, solved, stored, gamma0, threads in _solved(
                  surface, spacing, rings, orientation=orientation, pre_shear=pre_shear, skew=skew,
                  crossover=crossover, seg_i=seg_i, seg_j=seg_j, gamma0=gamma0, mode=mode, material=material,
                  blankholder_force=blankholder_force, friction=friction, sectors=sectors,
                  blankholder_model=blankholder_model, tolerance=tolerance, max_iterations=max_iterations,
                  max_turn=max_turn, factors=factors, progress=progress, threads=threads)]
    if len(blocks) == 1:
        return blocks[0]
    ds = xr.concat(blocks, dim=REALIZATION, data_vars="minimal", coords="minimal", compat="override",
                   join="override")
    return ds.assign_coords(realization=np.arange(sum(block.sizes[REALIZATION] for block in blocks)))


def drape_status(surface, spacing, rings, **options) -> np.ndarray:
    """The node status (R, 2n + 1, 2n + 1) of the drapes ``drape(surface, spacing, rings,
    **options)`` makes (the same arguments, checks and solve), without their Dataset:
    none of the per-cell and energy post-processing or its kernels, and no xarray. The
    placement check of ``uqdrape validate`` and of a run's preflight."""
    return np.concatenate([solved[1] for _, solved, _, _, _ in _solved(surface, spacing, rings, **options)])


def _solved(surface, spacing, rings, *, orientation=0.0, pre_shear=0.0, skew=0.0, crossover=(0.0, 0.0),
            seg_i=None, seg_j=None, gamma0=None, mode="geodesic", material=None, blankholder_force=0.0,
            friction=0.2, sectors=None, blankholder_model="slip", tolerance=1e-3, max_iterations=30,
            max_turn=10.0, factors=None, progress=None, threads=None):
    """``drape``'s arguments checked and broadcast, then its blocks of BLOCK realisations
    solved one after another: yields (problem, (P, status, turns, bending, iterations,
    converged), the block's stored inputs, its zero-energy angles in degrees, threads)."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if not isinstance(spacing, numbers.Real) or not np.isfinite(spacing) or spacing <= 0:
        raise ValueError(f"spacing must be a finite number > 0 (mm), got {spacing!r}")
    if not isinstance(rings, numbers.Integral) or rings < 1:
        raise ValueError(f"rings must be an integer >= 1, got {rings!r}")
    if mode == "energy" and material is None:
        raise ParameterError("material", "mode 'energy' needs a material card: a shipped card's name "
                             "(uqdrape.available_materials()) or a card file")
    materials = _material_list(material)
    if not isinstance(max_iterations, numbers.Integral) or max_iterations < 1:
        raise ValueError(f"max_iterations must be an integer >= 1, got {max_iterations!r}")
    for name, v in (("tolerance", tolerance), ("max_turn", max_turn)):
        if not np.isfinite(v) or v <= 0:
            raise ValueError(f"{name} must be > 0 (deg), got {v!r}")
    if threads is None:
        threads = default_threads()
    if not isinstance(threads, numbers.Integral) or threads < 1:
        raise ValueError(f"threads must be an integer >= 1, got {threads!r}")
    n = int(rings)
    shapes = dict(orientation=(orientation, 0), pre_shear=(pre_shear, 0), skew=(skew, 0),
                  crossover=(crossover, 1), seg_i=(seg_i, 2), seg_j=(seg_j, 2), gamma0=(gamma0, 2),
                  blankholder_force=(blankholder_force, 0), friction=(friction, 0))
    R = _batch_size(**shapes)
    if materials is not None and len(materials) not in (1, R):
        raise ValueError(f"material is a sequence of {len(materials)} materials; give one, or one per realisation "
                         f"(R = {R})")
    orientation = _per_realisation("orientation", orientation, (), R)
    pre_shear = _per_realisation("pre_shear", pre_shear, (), R)
    skew = _per_realisation("skew", skew, (), R)
    crossover = _per_realisation("crossover", crossover, (2,), R)
    seg_i = _segments("seg_i", seg_i, spacing, (2 * n, 2 * n + 1), R)
    seg_j = _segments("seg_j", seg_j, spacing, (2 * n + 1, 2 * n), R)
    if gamma0 is not None and not np.isfinite(gamma0).all():
        raise ValueError("gamma0 must be finite (deg)")
    gamma0 = np.zeros((R, 2 * n, 2 * n)) if gamma0 is None else _per_realisation("gamma0", gamma0, (2 * n, 2 * n), R)
    force = _per_realisation("blankholder_force", blankholder_force, (), R)
    mu = _per_realisation("friction", friction, (), R)
    if np.isnan(crossover).any():
        raise ValueError(f"crossover must be finite (mm), got NaN in {crossover[np.isnan(crossover).any(-1)][0]}")
    for name, a, lo in (("blankholder_force", force, 0.0), ("friction", mu, 0.0)):
        if not (np.isfinite(a).all() and (a >= lo).all()):
            raise ValueError(f"{name} must be finite and >= {lo:g}, got {float(a[~((a >= lo) & np.isfinite(a))][0]):g}")
    for name, a in (("orientation", orientation), ("pre_shear", pre_shear), ("skew", skew)):
        if not np.isfinite(a).all():
            raise ValueError(f"{name} must be finite (deg)")
    if (np.abs(pre_shear + skew) >= 90).any():
        raise ValueError("pre_shear + skew must lie strictly between -90 and 90 deg")

    psi = np.deg2rad(orientation)
    a1 = psi + 0.5 * np.deg2rad(skew)
    a2 = psi + np.deg2rad(90.0 - pre_shear) - 0.5 * np.deg2rad(skew)
    arm_angles = np.stack([a1, a2, a1 + np.pi, a2 + np.pi], axis=-1)
    e1 = np.stack([np.cos(psi), np.sin(psi)], -1)
    b = psi + np.deg2rad(90.0 - pre_shear)
    e2 = np.stack([np.cos(b), np.sin(b)], -1)
    tol = 1e-11 * max(float(surface.size), 1.0)
    BlankHolder(force, mu, sectors, blankholder_model)  # raises on bad sectors before any work
    stored = dict(orientation=orientation, pre_shear=pre_shear, skew=skew, crossover_x=crossover[:, 0],
                  crossover_y=crossover[:, 1], blankholder_force=force, friction=mu,
                  **{k: np.broadcast_to(np.asarray(v, dtype=float), (R,)) for k, v in (factors or {}).items()})
    for start in range(0, R, BLOCK):
        b = slice(start, start + BLOCK)
        prob = NetProblem(surface, float(spacing), n, crossover[b], arm_angles[b], seg_i[b], seg_j[b],
                          np.deg2rad(gamma0[b]), e1[b], e2[b], BlankHolder(force[b], mu[b], sectors, blankholder_model),
                          None if materials is None else materials[b] if len(materials) > 1 else materials, tol)
        if mode == "geodesic":
            P, status = build_geodesic(prob, threads)
            if progress is not None:
                progress(n)
            r = prob.R
            solved = (P, status, np.zeros((r, n, 4)), np.zeros(r), np.zeros(r, np.int32), np.ones(r, bool))
        else:
            solved = EnergyRings(prob, prob.material.bending_stiffness, np.deg2rad(tolerance),
                                 int(max_iterations), np.deg2rad(max_turn), threads).run(progress)
        yield prob, solved, {k: v[b] for k, v in stored.items()}, gamma0[b], threads


def cell_shear(P, threads=1):
    """Signed cell shear (rad), (R, 2n, 2n), of net positions P (R, N, N, 3).

    Same value as ``quad_shear`` per cell, with each unit edge computed once for the net
    (``kernels.net_shear``).
    """
    R, N = P.shape[:2]
    P = np.ascontiguousarray(P, float)
    out = np.empty((R, N - 1, N - 1))
    on_threads(threads, R, lambda r: net_shear(P[r], out[r]))
    return out


def node_mean(cells, threads=1):
    """Mean of the valid (finite) cells around each node; cells (R, 2n, 2n) -> (R, N, N), NaN
    where a node has no valid cell. Node shear is this mean of the cell shears."""
    R, m, _ = cells.shape
    cells = np.ascontiguousarray(cells, float)
    out = np.empty((R, m + 1, m + 1))
    on_threads(threads, R, lambda r: net_node_mean(cells[r], out[r]))
    return out


@functools.lru_cache(maxsize=8)
def _coords(R, n):
    """The coordinates of a drape Dataset of R realisations of an n-ring net, with their
    indexes built once per shape (building them was most of a single drape's time)."""
    import xarray as xr

    return xr.Coordinates({REALIZATION: np.arange(R), "i": np.arange(-n, n + 1), "j": np.arange(-n, n + 1),
                           "cell_i": np.arange(-n, n) + 0.5, "cell_j": np.arange(-n, n) + 0.5,
                           "ring": np.arange(1, n + 1), "arm": ["+i", "+j", "-i", "-j"], "quadrant": list(QUADRANTS)})


def _material_list(material):
    """``material`` as a list (one Material, or one per realisation), None for none. A
    sequence must agree on what the solver and the lock flags take from one card: locking
    angles, phi0 and bending stiffness."""
    if material is None:
        return None
    materials = list(material) if isinstance(material, (list, tuple)) else [material]
    if not materials:
        raise ValueError("material is an empty sequence; give a Material or one per realisation")
    first = materials[0]
    key = ("locking_angle_deg", "locking_angle_neg_deg", "phi0_deg", "bending_stiffness")
    if any(tuple(getattr(m, k) for k in key) != tuple(getattr(first, k) for k in key) for m in materials):
        raise ValueError(f"the materials of a batch must share {', '.join(key)}; they differ")
    return materials


def _dataset(prob, P, status, turns, bending, iterations, converged, mode, factors, gamma0_deg, threads):
    """The drape Dataset of one block; ``gamma0_deg`` is the caller's zero-energy angles (deg)."""
    import xarray as xr

    n = prob.n
    gamma = cell_shear(P, threads)
    material = prob.material
    if material is not None:
        if len(prob.materials) == 1:
            cell_e = material.cell_energy(gamma, prob.cell_s1, prob.cell_s2, prob.gamma0)
        else:  # one card per realisation
            cell_e = np.stack([m.cell_energy(gamma[r], prob.cell_s1[r], prob.cell_s2[r], prob.gamma0[r])
                               for r, m in enumerate(prob.materials)])
        shear_energy = np.nansum(cell_e, axis=(1, 2))
        locked = material.is_locked(gamma - prob.gamma0)
        # a node is locked when a valid cell next to it is (branch- and zero-angle-aware)
        near = node_mean(np.where(np.isfinite(gamma), locked, np.nan), threads)
        node_locked = np.where(np.isnan(near), np.nan, near > 0)
    else:
        shear_energy = np.full(prob.R, np.nan)
        locked = np.zeros(gamma.shape, bool)
        node_locked = np.full(P.shape[:-1], np.nan)
    bh = np.empty((prob.R, 4))
    bhk = prob.blankholder
    on_threads(threads, prob.R, lambda r: boundary_blankholder(
        n, n, P[r], prob.blank[r], prob.crossover[r], bhk.force[r], bhk.friction[r], bhk.kernel, bh[r]))
    node = (REALIZATION, "i", "j")
    cell = (REALIZATION, "cell_i", "cell_j")
    # to degrees in place, after every use in radians: fresh (R, N, N) copies cost page faults
    node_shear = node_mean(gamma, threads)
    np.rad2deg(node_shear, out=node_shear)
    np.rad2deg(gamma, out=gamma)
    total = np.nan_to_num(shear_energy) + bending + bh.sum(-1)
    variables = {
        "x": (node, P[..., 0], {"units": "mm", "long_name": "node x"}),
        "y": (node, P[..., 1], {"units": "mm", "long_name": "node y"}),
        "z": (node, P[..., 2], {"units": "mm", "long_name": "node z (height)"}),
        "shear": (node, node_shear,
                  {"units": "degree", "long_name": "node shear angle (mean of adjacent cells)"}),
        "status": (node, status, {"long_name": "node status", "units": "1", "flag_values": [s.value for s in Status],
                                  "flag_meanings": " ".join(s.name.lower() for s in Status)}),
        "cell_shear": (cell, gamma, {"units": "degree", "long_name": "signed cell shear angle"}),
        "cell_locked": (cell, locked, {"long_name": "cell sheared beyond the locking angle", "units": "1"}),
        "locked": (node, node_locked, {"units": "1", "long_name": "node next to a cell sheared beyond "
                                       "its branch's locking angle (1) or not (0); NaN: invalid node"}),
        "gamma0": (cell, gamma0_deg, {"units": "degree", "long_name": "zero-energy shear angle"}),
        "turn": ((REALIZATION, "ring", "arm"), np.rad2deg(turns),
                 {"units": "degree", "long_name": "generator-arm turn angle about the surface normal"}),
        "energy_shear": (REALIZATION, shear_energy, {"units": "J", "long_name": "shear energy"}),
        "energy_bending": (REALIZATION, bending, {"units": "J", "long_name": "generator-path bending energy"}),
        "energy_blankholder": (REALIZATION, bh.sum(-1), {"units": "J", "long_name": "blank-holder friction energy"}),
        "energy_blankholder_quadrant": ((REALIZATION, "quadrant"), bh,
                                        {"units": "J", "long_name": "blank-holder energy per quadrant"}),
        "energy_total": (REALIZATION, total, {"units": "J", "long_name": "total forming energy"}),
        "iterations": (REALIZATION, iterations, {"long_name": "minimiser iterations, all steps", "units": "1"}),
        "converged": (REALIZATION, converged, {"long_name": "minimiser converged at every step", "units": "1"}),
    }
    for name, value in factors.items():  # the per-realisation inputs (the force: uqdrape.schema.APPLIED_FORCE)
        inp = SOLVER_INPUTS.get(name)
        attrs = {"units": inp.units, "long_name": inp.long_name} if inp else {"units": "1", "long_name": f"sampled input {name}"}
        variables[inp.variable if inp else name] = (REALIZATION, np.asarray(value, dtype=float), attrs)
    coords = _coords(prob.R, n)
    return xr.Dataset(
        variables, coords=coords,
        attrs={"spacing_mm": prob.s, "rings": n, "mode": mode, "mould": prob.surface.describe(),
               "material": getattr(material, "name", "none"),
               "locking_angle_deg": float(getattr(material, "locking_angle_deg", np.nan) or np.nan),
               "blankholder_model": prob.blankholder.model,
               "locking_angle_neg_deg": float(getattr(material, "locking_angle_neg_deg", np.nan) or np.nan),
               "geometry_json": json.dumps({"kind": prob.surface.name, **prob.surface.params()}),
               "status_codes": Status.describe(), "uqdrape_version": __version__,
               "Conventions": "CF-1.8", **_frame_attrs(prob.surface)},
    )


def _frame_attrs(surface) -> dict:
    """A mesh mould turned by its press_direction: the dataset's frame and the rotation back
    to the tool's (node coordinates stay in the solver's, so chunks and resumes are the
    solver's own numbers; the VTK and FE exports turn them)."""
    R = surface.tool_rotation
    if R is None:
        return {}
    return {"frame": "solver: the tool turned so its press_direction is +z; tool = tool_rotation^T solver (mm)",
            "tool_rotation": [float(v) for v in R.ravel()]}
