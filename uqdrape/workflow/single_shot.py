"""The single-shot commands: one drape to files, material cards (list, show, derive from
an architecture) and exports of a drape or a run. Each returns what it wrote and a
summary; the CLI only prints."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..conventions import cf_encode
from ..drape import drape, unplaced_error
from ..ensemble import at, ring_progress, write_netcdf
from ..export import cut_files, fe_files, flat_files, laminate_files, levels, netcdf_file, open_result, vtk_files
from ..files import local_path, write_all, write_text_atomic
from ..errors import ParameterError
from ..geometry import build
from ..material import available_materials, load_material, plot_material
from ..material.architecture import derive_card, load_architecture, summed
from ..material.cards import card_material, card_text
from ..material.plot import plot_architecture, plot_sheartest
from ..material.sheartest import fit_card, read_rig
from ..report import plot_lines, plot_net
from ..schema import MAX_RINGS, MAX_TOLERANCE_DEG, PLY, SOLVER_INPUTS, SPACING_RANGE_MM, ply_dataset
from ..study.spec import Solver
from .preflight import WORKING_BYTES_PER_NODE, memory_bytes


def drape_to_files(geometry: str, params: dict, spacing: float, rings: int, out, *, material=None,
                   progress=True, command: str = "uqdrape drape", **options) -> tuple[list[Path], str]:
    """Drape one net (``uqdrape.drape.drape`` with ``options``) over mould ``geometry``
    and write ``OUT.nc`` (CF netCDF), ``OUT-net.png`` and ``OUT-lines.png``, all three or
    none; return the paths and a one-line summary. The inputs are checked first against
    the same physical ranges a study's are (``check_drape_inputs``), and the net against
    this machine's memory; the mould as ``uqdrape validate`` checks a study's: the
    crossover in its domain, and a drape with more than a study's default failure budget
    of its nodes unplaced refused, not written. ``command`` is recorded as the file's history."""
    check_drape_inputs(spacing, rings, options, material)
    out = local_path(out, "out")
    surface = build(geometry, **params)
    x, y = options.get("crossover", (0.0, 0.0))
    off = surface.crossover_error(x, y)
    if off:
        raise ParameterError("crossover", f"crossover = ({x:g}, {y:g}) mm is invalid: {off}")
    card = load_material(material) if material else None
    mode = options.get("mode", "geodesic")
    # a ring k/n counter: a bar on a terminal, elsewhere a line every PLAIN_EVERY s of a long drape
    bar = ring_progress(rings, mode, progress)
    try:
        ds = drape(surface, spacing, rings, material=card, progress=lambda k: bar.update(k - bar.n), **options)
    finally:
        bar.close()
    refused = unplaced_error(ds.status.values[0], Solver.failure_budget, "a study's default solver.failure_budget",
                             "the drape")
    if refused:
        raise ParameterError("rings", refused)
    encoded, encoding = cf_encode(ds, title=f"uqdrape {mode} drape of {surface.describe()}", history=command)
    nc = out.with_suffix(".nc")
    written = write_all({
        nc: lambda tmp: write_netcdf(encoded, tmp, encoding, target=nc),
        out.with_name(out.name + "-net.png"): lambda tmp: plot_net(
            ds, tmp, title=f"{surface.describe()}, {mode} drape, s = {spacing} mm"),
        out.with_name(out.name + "-lines.png"): lambda tmp: plot_lines(ds, tmp),
    })
    shear = ds.shear.values
    summary = (f"valid nodes {float((ds.status == 0).mean()):.1%}; shear {np.nanmin(shear):.1f} to "
               f"{np.nanmax(shear):.1f} deg; energy shear {float(ds.energy_shear[0]):.4g} J, blank-holder "
               f"{float(ds.energy_blankholder[0]):.4g} J; converged {bool(ds.converged[0])} "
               f"({int(ds.iterations[0])} iterations)")
    return written, summary


def check_drape_inputs(spacing: float, rings: int, options: dict, material: str | None = None) -> None:
    """Refuse a single drape's inputs outside the physical ranges a study's must keep
    (``uqdrape.schema``: the solver's scalar inputs, MAX_RINGS; a pre-shear short of the
    card ``material``'s locking angle) or whose net would need more than half this
    machine's memory; ParameterError names the drape argument."""
    low, high = SPACING_RANGE_MM
    if not (isinstance(spacing, (int, float)) and math.isfinite(spacing) and low <= spacing < high):
        raise ParameterError("spacing", f"spacing must be a length in [{low:g}, {high:g}) mm, got {spacing!r}")
    if not 1 <= rings <= MAX_RINGS:
        raise ParameterError("rings", f"rings must be an integer in [1, {MAX_RINGS}], got {rings!r}")
    nodes = (2 * rings + 1) ** 2
    if nodes * WORKING_BYTES_PER_NODE > memory_bytes() / 2:
        raise ParameterError("rings", f"rings = {rings}: one drape of {nodes:,} nodes needs about "
                                      f"{nodes * WORKING_BYTES_PER_NODE / 2**30:.3g} GiB, more than half of this "
                                      f"machine's {memory_bytes() / 2**30:.3g} GiB")
    for name, value in options.items():
        inp = SOLVER_INPUTS.get(name)
        if inp is not None and np.ndim(value) == 0 and not (math.isfinite(value) and inp.admits(value)):
            raise ParameterError(name, f"{name} = {value:g} is invalid: {name} {inp.describe_range()}")
    turn = options.get("pre_shear", 0.0) + options.get("skew", 0.0)
    if np.ndim(turn) == 0 and not abs(turn) < 90.0:
        raise ParameterError(("pre_shear", "skew"), f"pre_shear + skew = {turn:g} is invalid: it must lie in "
                                                    "(-90, 90) degrees")
    locked = material and load_material(material).blank_shear_error(options.get("pre_shear", 0.0))
    if locked:
        raise ParameterError("pre_shear", f"a blank pre-sheared {options.get('pre_shear', 0.0):g} deg is {locked}")
    tolerance = options.get("tolerance", 1e-3)
    if not (math.isfinite(tolerance) and 0 < tolerance <= MAX_TOLERANCE_DEG):
        raise ParameterError("tolerance", f"tolerance = {tolerance:g} is invalid: the minimiser's tolerance on "
                                          f"turn angles must lie in (0, {MAX_TOLERANCE_DEG:g}] degrees")


def material_list() -> list[tuple[str, str]]:
    """(name, description) of every shipped material card."""
    return [(name, load_material(name).description) for name in available_materials()]


def material_text(name: str, plot=None) -> str:
    """What a card says (locking angles, bending stiffness, note); ``plot``: also write its
    curves to that PNG."""
    plot = local_path(plot, "plot") if plot else plot
    m = load_material(name)
    text = (f"{m.name}: {m.description}\nlocking angle +{m.locking_angle_deg} / -{m.locking_angle_neg_deg} deg, "
            f"bending stiffness {m.bending_stiffness} N m^2\n{m.note}")
    if plot:
        text += f"\nwrote {plot_material(m, plot)}"
    return text


def derive_material(source: str, out, plot=None) -> str:
    """Derive a card from architecture ``source`` (a TOML file or a shipped name) into
    ``out`` (.toml), with the thesis Fig 4.18 picture if ``plot`` (True: next to the
    card, or a PNG path); a card that would not load is not written. Returns the summary."""
    out, plot = local_path(out, "out"), local_path(plot, "plot") if isinstance(plot, (str, Path)) else plot
    arch = load_architecture(source)
    terms = summed(arch)
    doc = derive_card(arch, name=out.stem, source=Path(source).name, terms=terms)
    text = card_text(doc, f"Material card derived by `uqdrape materials derive {Path(source).name}`: "
                          "regenerate it, do not edit it.")
    material = card_material(text, str(out))
    gamma0 = doc["architecture"]["zero_force_angle_deg"]
    out.parent.mkdir(parents=True, exist_ok=True)
    png = None
    if plot:  # the picture first: if it fails, no card is left behind either
        png = out.with_suffix(".png") if plot is True else Path(plot)
        png.parent.mkdir(parents=True, exist_ok=True)
        plot_architecture(arch, png, terms, gamma0)
    write_text_atomic(out, text)
    summary = (f"wrote {out}: {material.name}, zero-force angle {gamma0:.2f} deg, locking "
               f"+{material.locking_angle_deg:g} / -{material.locking_angle_neg_deg:g} deg (pre-strain "
               f"{100 * arch.prestrain:.3g} %, beta {arch.beta:.4g})")
    return summary + (f"\nwrote {png}" if png else "")


def fit_material(rig, out, plot=None) -> str:
    """Fit a card to the shear tests named by rig file ``rig`` (thesis ch. 3, see
    ``uqdrape.material.sheartest``) and write it to ``out`` (.toml), with the normalisation
    figure if ``plot`` (True: next to the card, or a PNG path); a card that would not load
    is not written. Returns the summary, warnings (kappa < 2) on lines of their own."""
    out, plot = local_path(out, "out"), local_path(plot, "plot") if isinstance(plot, (str, Path)) else plot
    rig_file = read_rig(rig)
    result = fit_card(rig_file, rig_file.name or out.stem, Path(rig).name)
    text = card_text(result.doc, f"Material card fitted by `uqdrape materials fit {Path(rig).name}` from shear "
                                 "tests: regenerate it, do not edit it.")
    material = card_material(text, str(out))
    png = None
    if plot:  # the picture first: if it fails, no card is left behind either
        png = out.with_suffix(".png") if plot is True else Path(plot)
        plot_sheartest(result, png)
    write_text_atomic(out, text)
    record = result.doc["sheartest"]
    branches = "; ".join(
        f"{branch}: {len(record[branch]['files'])} specimens to {material.curve(branch)[0][-1]:g} deg, N_s "
        f"{material.curve(branch)[1][-1]:.4g} N/m there, fit residual <= {max(record[branch]['residual_rms_n']):.3g} "
        f"{record['force_unit']}"
        for branch in ("positive", "negative") if branch in record)
    lines = [f"wrote {out}: {material.name} ({branches})", *(f"warning: {w}" for w in result.warnings)]
    return "\n".join(lines + ([f"wrote {png}"] if png else []))


#: What ``export_result`` writes (``to``).
EXPORT_FORMATS = ("vtk", "fe", "flat", "cut", "netcdf")


def export_result(result, to, *, out=None, mesh=None, tolerance=None, reference=None, flavours=("abaqus",),
                  trim=None, ply=None, thickness=1.0, realizations=0, variance=0.99) -> tuple[list, list[str]]:
    """Export a drape file, a run folder or a store URL ``result`` as ``to`` (some of
    "vtk", "fe", "flat", "cut", "netcdf"); every file is computed first and written
    together, all or nothing, under the stem ``out`` (default: the drape file without
    .nc, or the run's ``export/NAME``, in a store put under its URL). ``flavours``: the
    FE solvers' cards for "fe"; ``trim``: the part's edge (plan CSV) for "cut" (default:
    the mould's own outline), ``ply`` its label. A laminate's "vtk", "flat" and "cut" are
    written per ply (``STEM-ply-NAME...``, each cut labelled with its ply), and its "fe" is
    the laminate handoff (``uqdrape.export.laminate``: plies ``thickness`` mm thick, the
    first ``realizations`` decks, KL modes holding ``variance`` of the angles' variance).
    Returns the paths (URLs in a store) and the lines to tell the user (the FE mapping counts)."""
    unknown = [t for t in to if t not in EXPORT_FORMATS]
    if unknown or not to:
        raise ValueError(f"to must name some of {', '.join(EXPORT_FORMATS)}; got {list(to)!r}")
    if "fe" in to and not mesh:
        raise ParameterError("mesh", "an fe export needs mesh, the part's surface mesh: a "
                         "file meshio reads (.inp, .msh, .vtu, .stl, ...)")
    out = local_path(out, "out") if out else None
    ds, is_ensemble = open_result(result)
    name = at(result).name if is_ensemble else Path(result).stem
    options = dict(mesh=mesh, tolerance=tolerance, reference=reference, flavours=flavours, trim=trim,
                   ply=ply or name, history=f"uqdrape export {result} --to {' '.join(to)}",
                   laminate=dict(thickness_mm=thickness, realizations=realizations, variance=variance))
    if out or not is_ensemble:
        return _export(ds, is_ensemble, to, out or Path(result).with_suffix(""), **options)
    where = at(result)
    with where.writing("export") as folder:
        written, notes = _export(ds, is_ensemble, to, folder / name, **options)
    return [where.path_of(f"export/{path.relative_to(folder).as_posix()}") for path in written], notes


def _export(ds, is_ensemble: bool, to, stem: Path, *, mesh, tolerance, reference, flavours, trim, ply,
            history, laminate) -> tuple[list[Path], list[str]]:
    """The files of ``export_result`` under ``stem``."""
    writers, notes = {}, []
    if "netcdf" in to:
        writers.update(netcdf_file(ds, stem, history))
    plies = [(name, ply_dataset(ds, name), stem.with_name(f"{stem.name}-ply-{name}")) for name in ds[PLY].values] \
        if PLY in ds.dims else [(ply, ds, stem)]
    for label, one, base in plies:
        levels_ = levels(one, is_ensemble) if set(to) - {"netcdf"} else []
        for level in levels_ if reference is not None else ():
            level.orientation = reference
        if "vtk" in to:
            writers.update(vtk_files(levels_, one, base))
        if "fe" in to and PLY not in ds.dims:
            fe, statuses = fe_files(levels_, one, mesh, base, tolerance, flavours)
            writers.update(fe)
            counts = [int(n) for n in np.bincount(statuses[0], minlength=3)]
            notes.append(f"{mesh}: {sum(counts)} elements, {counts[0]} on the net, {counts[1]} outside it, "
                         f"{counts[2]} off the mould (flagged in map_status and each flavour's unmapped set)")
        if "flat" in to:
            writers.update(flat_files(levels_, base))
        if "cut" in to:
            writers.update(cut_files(levels_, one, base, trim=trim, ply=label))
    if "fe" in to and PLY in ds.dims:
        writers.update(laminate_files(ds, mesh, stem, flavours=flavours, tolerance_mm=tolerance, history=history,
                                      **laminate))
        notes.append(f"{mesh}: the laminate of {ds.sizes[PLY]} plies (elements a ply does not reach are listed in "
                     "each flavour's unmapped set of that ply)")
    return write_all(writers), notes
