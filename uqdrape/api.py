"""The public Python API, exported at the top level of the package (``uqdrape.__all__``).

Each function is a thin, documented door to the engine that the command line uses as well:
it imports what it needs when it is called, so ``import uqdrape`` stays cheap. Units at
every interface: lengths mm, forces N, energies J, angles degrees.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .study import Study

if TYPE_CHECKING:
    import xarray as xr

    from .geometry import Surface
    from .material import Material

#: A local path, or for a run's output also an fsspec URL (``s3://bucket/prefix``).
PathLike = str | os.PathLike


def load_study(path: PathLike, overrides: Mapping[str, Any] | None = None) -> Study:
    """Read and validate a study file (TOML).

    Unknown keys, wrong types and impossible values are refused before anything runs.
    The study-file reference lists every key with its units and valid values.

    Parameters
    ----------
    path : str or os.PathLike
        The study file; paths inside it (a mesh, measurements) are relative to its folder.
    overrides : mapping of str to value, optional
        Dotted keys set as if the file held them, each validated like the file's own:
        ``{"study.realizations": 16, "solver.rings": 12}`` for a small trial run.

    Returns
    -------
    Study
        The validated study (a frozen dataclass; ``study.output_dir`` is where a run goes).

    Raises
    ------
    StudyError
        The first problem found, naming the file, the key and what would be valid.

    Examples
    --------
    >>> import tempfile, uqdrape as ud
    >>> path = ud.copy_example("nosecone-zero-angle", tempfile.mkdtemp())
    >>> study = ud.load_study(path, {"study.realizations": 8})
    >>> study.name, study.realizations, study.force_levels
    ('nosecone-zero-angle', 8, (126.0,))
    """
    from .study import load_study as load

    return load(path, None if overrides is None else dict(overrides))


def validate_study(path: PathLike) -> Study:
    """Read a study file and check it as a run would, before anything is draped.

    Beyond :func:`load_study` (keys, types, ranges), checks this machine (memory for a
    chunk, disk for the whole ensemble, a writable output folder) and the physics (the
    first realisation's net can be placed on the mould).

    Parameters
    ----------
    path : str or os.PathLike
        The study file (TOML).

    Returns
    -------
    Study
        The validated study.

    Raises
    ------
    StudyError
        As :func:`load_study`, or a chunk or the ensemble this machine cannot hold, or a
        first net that cannot be placed (naming the key to change, e.g. ``solver.rings``).

    Examples
    --------
    >>> import tempfile, uqdrape as ud
    >>> study = ud.validate_study(ud.copy_example("pan-corner-lock", tempfile.mkdtemp()))
    >>> study.name, study.solver.rings
    ('pan-corner-lock', 16)
    """
    from .workflow.preflight import validate_study as validate

    return validate(path)


def run_study(study: Study | PathLike, *, out: PathLike | None = None, scheduler: str | None = None,
              workers: int | None = None, chunk_size: int | None = None, method: str | None = None,
              resume: bool = True, progress: bool = True) -> Path | str:
    """Run a study: its Monte Carlo ensemble, its sensitivity sample or its blank-holder design.

    Realisations are draped in chunks by dask, each chunk written as it finishes; a run
    stopped part-way resumes from its finished chunks. Results are the same numbers for
    any chunk size and any number of workers.

    Parameters
    ----------
    study : Study or str or os.PathLike
        A study (:func:`load_study`) or the path of a study file.
    out : str or os.PathLike, optional
        Where the run goes: a folder (of netCDF chunks), or an fsspec URL
        (``s3://bucket/prefix``, ``file:///abs/path``) of one zarr store. Default: the
        study's ``[output] directory`` (``results/NAME`` under the working folder).
    scheduler : str, optional
        Address of a running dask.distributed scheduler (``tcp://host:8786``); default:
        local worker processes.
    workers : int, optional
        Local worker processes (default: all cores).
    chunk_size : int, optional
        Realisations per chunk (default: the study's).
    method : {"sobol", "morris", "none"}, optional
        Another sensitivity method than the study's; its run goes to ``OUT-METHOD``.
    resume : bool, default True
        Keep the chunks an earlier run of the same study finished.
    progress : bool, default True
        Show a progress bar and what the run does on stderr.

    Returns
    -------
    pathlib.Path or str
        The run's output folder (a URL for a store): give it to :func:`open_ensemble`,
        :func:`open_sensitivity`, :func:`open_design` or :func:`write_report`.

    Examples
    --------
    >>> import tempfile, uqdrape as ud
    >>> work = tempfile.mkdtemp()
    >>> study = ud.load_study(ud.copy_example("nosecone-zero-angle", work),
    ...                       {"study.realizations": 4, "solver.rings": 8})
    >>> out = ud.run_study(study, out=f"{work}/run", workers=1, progress=False)
    >>> ud.open_ensemble(out).sizes["realization"]
    4
    """
    from .workflow.run import run_study as run

    return run(located(study, out), scheduler=scheduler, workers=workers, chunk_size=chunk_size, method=method, resume=resume,
               progress=progress)


def located(study: Study | PathLike, out: PathLike | None = None) -> Study:
    """The study (or the study file's), its output going to ``out`` (a folder or an fsspec
    URL) if given: where :func:`run_study` and ``uqdrape run --out`` put a run."""
    import dataclasses

    from .files import location

    study = study if isinstance(study, Study) else load_study(study)
    return study if out is None else dataclasses.replace(study, output_dir=location(out))


def open_ensemble(run: PathLike) -> xr.Dataset:
    """Open a finished run's drapes as one lazy (dask-backed) xarray Dataset.

    Parameters
    ----------
    run : str or os.PathLike
        A run's output folder or store URL (what :func:`run_study` returns).

    Returns
    -------
    xarray.Dataset
        Dims ``(blankholder_force, realization, i, j)`` (the force of length 1 without a
        sweep; nodes ``i, j`` in ``-rings..rings``); variables such as ``shear`` (deg),
        ``x, y, z`` (mm) and ``status`` per node, the sampled factors per realisation.
        One dask chunk per stored chunk: nothing is read until it is computed.

    Raises
    ------
    FileNotFoundError
        ``run`` holds no run, or some of its chunks are missing (run the study again to
        resume it).

    Examples
    --------
    >>> ds = ud.open_ensemble(out)  # doctest: +SKIP
    >>> float(ds["shear"].isel(blankholder_force=0, i=0, j=0).mean())  # doctest: +SKIP
    0.0
    """
    from .ensemble import open_ensemble as open_

    return open_(run)


def open_sensitivity(run: PathLike) -> tuple[xr.Dataset, xr.Dataset] | None:
    """The sensitivity indices of a finished sensitivity run (``[sensitivity] method``).

    Parameters
    ----------
    run : str or os.PathLike
        The run's output folder or store URL.

    Returns
    -------
    (xarray.Dataset, xarray.Dataset) or None
        The indices of the scalar quantities of interest (dims ``factor, qoi,
        blankholder_force``: ``S1, ST`` and their ``_conf`` half-widths for Sobol', ``mu,
        mu_star, mu_star_conf, sigma`` for Morris), and the per-node index maps of the shear (dims ``factor, i, j,
        blankholder_force``); None if the run holds no sensitivity results.

    Examples
    --------
    >>> indices, maps = ud.open_sensitivity(out)  # doctest: +SKIP
    >>> indices["ST"].sel(qoi="max_abs_shear").to_series()  # doctest: +SKIP
    """
    from .workflow.run import open_sensitivity as open_

    return open_(run)


def open_design(run: PathLike) -> xr.Dataset:
    """The result of a finished blank-holder design run (a study with ``[design]``).

    Parameters
    ----------
    run : str or os.PathLike
        The design run's output folder or store URL.

    Returns
    -------
    xarray.Dataset
        Every candidate design evaluated (its force, sectors, friction and objective with
        confidence limits), the optimum and the baseline, and a one-line ``summary``
        attribute.

    Raises
    ------
    FileNotFoundError
        ``run`` holds no finished design.

    Examples
    --------
    >>> design = ud.open_design(ud.run_study("design-nosecone-symmetrise.toml"))  # doctest: +SKIP
    >>> print(design.attrs["summary"])  # doctest: +SKIP
    """
    from .design import DESIGN_FILE
    from .ensemble import at

    ds = at(run).read_dataset(DESIGN_FILE)
    if ds is None:
        raise FileNotFoundError(f"{run} holds no finished design ({DESIGN_FILE}); run a [design] study into it first")
    return ds


def node_statistics(ensemble: xr.Dataset, var: str = "shear", quantiles: Sequence[float] = (0.05, 0.5, 0.95),
                    confidence: float = 0.95) -> xr.Dataset:
    """Per-node statistics of an ensemble variable with their confidence limits.

    Parameters
    ----------
    ensemble : xarray.Dataset
        An ensemble (:func:`open_ensemble`).
    var : str, default "shear"
        The variable; its units are those of the results (``shear``: deg).
    quantiles : sequence of float, default (0.05, 0.5, 0.95)
        Probabilities in (0, 1) of the quantiles to estimate.
    confidence : float, default 0.95
        Level of the confidence limits.

    Returns
    -------
    xarray.Dataset
        Reduced along ``realization``, other dims kept (``blankholder_force, i, j``):
        ``mean, sd, skewness, count`` (valid realisations), ``mean_lower, mean_upper``
        (Student t) and, along ``quantile``, ``quantile_value, quantile_lower,
        quantile_upper`` (distribution-free order statistics). In memory.

    Examples
    --------
    >>> stats = ud.node_statistics(ud.open_ensemble(out))  # doctest: +SKIP
    >>> stats["sd"].isel(blankholder_force=0).plot()  # doctest: +SKIP
    """
    from .stats import node_statistics as stats

    return stats(ensemble, var, quantiles, confidence)


def exceedance_probability(ensemble: xr.Dataset, threshold_deg: float | Sequence[float] | None = None,
                           var: str = "shear", confidence: float = 0.95) -> xr.Dataset:
    """Per-node probability that ``|var|`` exceeds a threshold (e.g. the locking angle), with limits.

    Parameters
    ----------
    ensemble : xarray.Dataset
        An ensemble (:func:`open_ensemble`).
    threshold_deg : float or sequence of float, optional
        Threshold(s) in degrees (a sequence adds a ``threshold`` dim); default: the
        fabric's locking angle (the ensemble's ``locking_angle_deg`` attribute).
    var : str, default "shear"
        The variable compared (deg).
    confidence : float, default 0.95
        Level of the Wilson interval.

    Returns
    -------
    xarray.Dataset
        ``probability, probability_lower, probability_upper`` (1), ``exceed_count`` and
        ``count`` per node (dims ``blankholder_force, i, j``).

    Examples
    --------
    >>> risk = ud.exceedance_probability(ud.open_ensemble(out), 40.0)  # doctest: +SKIP
    >>> float(risk["probability"].max())  # doctest: +SKIP
    """
    from .stats import exceedance_probability as exceedance

    return exceedance(ensemble, threshold_deg, var, confidence)


def line_statistics(ensemble: xr.Dataset, kind: str = "max", confidence: float = 0.95) -> xr.Dataset:
    """Statistics of the shear along the four max-shear (or min-shear) lines from the crossover.

    Parameters
    ----------
    ensemble : xarray.Dataset
        An ensemble (:func:`open_ensemble`).
    kind : {"max", "min"}, default "max"
        The max-shear lines (the four quadrant diagonals from the crossover, dim
        ``quadrant``) or the min-shear lines (the four generator arms, dim ``arm``).
    confidence : float, default 0.95
        Level of the mean's confidence limits.

    Returns
    -------
    xarray.Dataset
        Per line and node ``k`` along it (other dims kept): ``shear_mean, shear_sd,
        shear_skewness, shear_mean_lower, shear_mean_upper`` (deg), the same of the
        distance from the crossover with prefix ``distance_`` (mm), and ``count``.

    Examples
    --------
    >>> lines = ud.line_statistics(ud.open_ensemble(out))  # doctest: +SKIP
    """
    from .stats import line_statistics as lines

    return lines(ensemble, kind, confidence)


def realization_qois(ensemble: xr.Dataset, qoi: Sequence[str] | None = None) -> xr.Dataset:
    """The scalar quantities of interest of every drape (what sensitivity ranks, designs optimise).

    Parameters
    ----------
    ensemble : xarray.Dataset
        An ensemble (:func:`open_ensemble`).
    qoi : sequence of str, optional
        Names of ``uqdrape.stats.QOIS`` (e.g. ``"max_abs_shear"`` deg, ``"energy_shear"`` J);
        default: those sensitivity studies rank.

    Returns
    -------
    xarray.Dataset
        One variable per quantity, dims ``(blankholder_force, realization)``, with units.

    Examples
    --------
    >>> q = ud.realization_qois(ud.open_ensemble(out), ["max_abs_shear"])  # doctest: +SKIP
    >>> q["max_abs_shear"].mean("realization")  # doctest: +SKIP
    """
    from .stats import SENSITIVITY_QOIS
    from .stats import realization_qois as qois

    return qois(ensemble, SENSITIVITY_QOIS if qoi is None else tuple(qoi))


def rare_probability(study: Study | PathLike, run: PathLike | None = None, *, resume: bool = True,
                     progress: bool = True) -> dict:
    """Estimate the rare exceedance probability a study asks for (its ``[study] rare``).

    Subset simulation or importance sampling on the drape itself, at every blank-holder
    force level; the record is written to the run folder (``rare.json``) and kept for a
    resumed run of the same study.

    Parameters
    ----------
    study : Study or str or os.PathLike
        A study with a ``[study] rare`` table, or its file.
    run : str or os.PathLike, optional
        The folder the record goes to (default: the study's output folder).
    resume : bool, default True
        Return the record already there if it is of this study.
    progress : bool, default True
        Say on stderr what is estimated.

    Returns
    -------
    dict
        The record: the quantity, threshold and method, and per force level (``levels``)
        the probability, its coefficient of variation and interval, and the drapes used.

    Examples
    --------
    >>> record = ud.rare_probability("my-rare-study.toml")  # doctest: +SKIP
    >>> record["levels"][0]["probability"]  # doctest: +SKIP
    """
    from .workflow.rare import rare_probabilities

    study = study if isinstance(study, Study) else load_study(study)
    if study.rare is None:
        raise ValueError(f"{study.path}: the study has no [study] rare table; add one to estimate a rare probability")
    return rare_probabilities(study, study.output_dir if run is None else run, resume=resume, progress=progress)


def write_report(run: PathLike, out_dir: PathLike | None = None, formats: Sequence[str] = ()) -> Path | str:
    """Write the report of a finished run: figures (PNG) and an HTML page.

    Parameters
    ----------
    run : str or os.PathLike
        The run's output folder or store URL (an ensemble, sensitivity or design run).
    out_dir : str or os.PathLike, optional
        The report's folder (default: ``RUN/report``).
    formats : sequence of {"svg", "pdf"}, optional
        Vector copies of the figures beside the PNGs.

    Returns
    -------
    pathlib.Path or str
        The report's ``index.html``.

    Examples
    --------
    >>> page = ud.write_report(out)  # doctest: +SKIP
    """
    from .workflow.run import run_report

    return run_report(run, out_dir, formats=tuple(formats))


def export_result(result: PathLike, to: Sequence[str], *, out: PathLike | None = None, mesh: PathLike | None = None,
                  flavours: Sequence[str] = ("abaqus",), trim: PathLike | None = None, ply: str | None = None,
                  tolerance: float | None = None, reference: float | None = None,
                  thickness: float | Sequence[float] = 1.0, realizations: int = 0,
                  variance: float = 0.99) -> tuple[list, list[str]]:
    """Export a drape file or a run for other tools: all files computed first, then written together.

    Parameters
    ----------
    result : str or os.PathLike
        A single drape's netCDF file (:func:`drape_mould`'s dataset written with
        ``to_netcdf``, or ``uqdrape drape``'s), a run folder or a store URL.
    to : sequence of {"vtk", "fe", "flat", "cut", "netcdf"}
        What to write: VTK of the net, FE cards with fibre directions per element of
        ``mesh``, the flat pattern, a cutting pattern, one CF netCDF file.
    out : str or os.PathLike, optional
        Output path stem (default: the drape file without ``.nc``, or ``RUN/export/NAME``).
    mesh : str or os.PathLike, optional
        The part's surface mesh (mm; any format meshio reads): needed for ``"fe"``.
    flavours : sequence of {"abaqus", "lsdyna", "nastran"}, default ("abaqus",)
        The FE solvers' cards for ``"fe"``.
    trim : str or os.PathLike, optional
        The part's edge for ``"cut"``: a closed plan polyline, CSV ``x_mm,y_mm``.
    ply : str, optional
        The ply label on the cutting pattern.
    tolerance : float, optional
        How far (mm) an element may lie from the mould for ``"fe"`` (default: the spacing).
    reference : float, optional
        Plan angle (deg) that fibre deviations are measured from (default: the orientation).
    thickness : float or sequence of float, default 1.0
        A laminate's cured ply thickness (mm) for ``"fe"``: one for all plies, or one per ply.
    realizations : int, default 0
        A laminate's Monte Carlo decks for ``"fe"``: one per realisation, the first ``realizations``.
    variance : float, default 0.99
        Share of a laminate's yarn-angle variance its Karhunen-Loeve modes keep, in (0, 1].

    A laminate run (a study with ``[[ply]]``) writes ``"vtk"``, ``"flat"`` and ``"cut"``
    per ply, and its ``"fe"`` is the laminate handoff (``uqdrape.export.export_laminate``).

    Returns
    -------
    (list, list of str)
        The paths written (URLs in a store) and notes (the FE mapping's counts).

    Examples
    --------
    >>> paths, notes = ud.export_result("drape.nc", ["vtk", "flat"])  # doctest: +SKIP
    """
    from .workflow.single_shot import export_result as export

    return export(result, tuple(to), out=out, mesh=mesh, tolerance=tolerance, reference=reference,
                  flavours=tuple(flavours), trim=trim, ply=ply, thickness=thickness, realizations=realizations,
                  variance=variance)


def mould(kind: str, **params: Any) -> Surface:
    """A mould: an analytic surface or a triangle mesh.

    Parameters
    ----------
    kind : str
        ``"plate"``, ``"cylinder"``, ``"hemisphere"``, ``"cone"``, ``"nose_cone"``,
        ``"double_dome"``, ``"saddle"`` or ``"mesh"`` (``uqdrape.geometry.KINDS``).
    **params
        Its shape parameters in mm (e.g. ``radius=100`` for a hemisphere; for a mesh
        ``path=`` a file trimesh reads: STL, OBJ, PLY, OFF); each class in
        ``uqdrape.geometry`` documents its own, with their defaults.

    Returns
    -------
    uqdrape.geometry.Surface
        The mould, pressed along -z.

    Raises
    ------
    ValueError
        An unknown kind or parameter, or an impossible value.

    Examples
    --------
    >>> import uqdrape as ud
    >>> dome = ud.mould("hemisphere", radius=100.0)
    >>> round(float(dome.height(0.0, 0.0)), 6)
    100.0
    """
    from .geometry import build

    return build(kind, **params)


def drape_mould(mould: Surface, spacing: float = 5.0, rings: int = 20, *, material: str | Material | None = None,
                mode: str = "geodesic", progress: bool = False, **options: Any) -> xr.Dataset:
    """Drape one pin-jointed net of fabric over a mould.

    Parameters
    ----------
    mould : uqdrape.geometry.Surface
        The mould (:func:`mould`).
    spacing : float, default 5.0
        Fibre spacing of the flat fabric, mm.
    rings : int, default 20
        The net has ``(2 * rings + 1) ** 2`` nodes around the crossover.
    material : str or Material, optional
        A material card: a shipped card's name (:func:`available_materials`), a card's
        path, or a Material (:func:`load_material`). Needed for ``mode="energy"``.
    mode : {"geodesic", "energy"}, default "geodesic"
        Straightest fibre paths from the crossover, or paths steered to minimise the
        shear and blank-holder energy.
    progress : bool, default False
        Show the rings placed on stderr.
    **options
        The process and fabric settings of ``uqdrape.drape.drape``: ``orientation`` (deg,
        fibre 1 from x), ``pre_shear`` (deg), ``skew`` (deg), ``crossover`` ((x, y) mm),
        ``blankholder_force`` (N), ``friction`` (-), ``blankholder_model`` ("slip",
        "radial"), ``tolerance`` (deg).

    Returns
    -------
    xarray.Dataset
        One realisation (dim ``realization`` of length 1) on nodes ``i, j``: positions
        ``x, y, z`` (mm), ``shear`` (deg), ``status`` (0 placed), the energies (J) and
        the minimiser's convergence.

    Raises
    ------
    ValueError
        An input outside its physical range, naming it.

    Examples
    --------
    >>> import uqdrape as ud
    >>> net = ud.drape_mould(ud.mould("hemisphere", radius=100.0), spacing=5.0, rings=10)
    >>> dict(net["shear"].sizes)
    {'realization': 1, 'i': 21, 'j': 21}
    """
    from .drape import drape
    from .ensemble.progress import ring_progress
    from .workflow.single_shot import check_drape_inputs

    named = material if isinstance(material, str | os.PathLike) else None
    check_drape_inputs(spacing, rings, options, named and str(named))
    card = load_material(material) if named is not None else material
    with ring_progress(rings, mode, progress) as bar:
        return drape(mould, spacing, rings, material=card, mode=mode, progress=lambda k: bar.update(k - bar.n),
                     **options)


def available_materials() -> list[str]:
    """The names of the material cards shipped with uqdrape.

    Returns
    -------
    list of str
        Sorted card names, for :func:`load_material` or a study's ``[fabric] material``.

    Examples
    --------
    >>> import uqdrape as ud
    >>> "ebxhd936_like" in ud.available_materials()
    True
    """
    from .material import available_materials as names

    return names()


def load_material(card: PathLike) -> Material:
    """A fabric's material card: its shear curves, locking angles and bending stiffness.

    Parameters
    ----------
    card : str or os.PathLike
        A shipped card's name (:func:`available_materials`), or the path of a TOML card
        or of a CSV of shear curves (columns ``angle_deg, ns_positive, ns_negative``:
        deg, N/m).

    Returns
    -------
    uqdrape.material.Material

    Examples
    --------
    >>> import uqdrape as ud
    >>> card = ud.load_material("ebxhd936_like")
    >>> card.locking_angle_deg > 0
    True
    """
    from .material import load_material as load

    return load(card)


def derive_material(architecture: PathLike, out: PathLike, plot: bool | PathLike | None = None) -> str:
    """Derive a material card from a fabric architecture (thesis ch. 4: stitch and compaction).

    Parameters
    ----------
    architecture : str or os.PathLike
        A shipped architecture's name (e.g. ``"fge106hd"``) or an architecture TOML file.
    out : str or os.PathLike
        The card to write (``.toml``); load it with :func:`load_material`.
    plot : bool or str or os.PathLike, optional
        Also draw each term's contribution: True beside the card, or a PNG path.

    Returns
    -------
    str
        A summary: zero-force angle and locking angles (deg) of the card written.

    Examples
    --------
    >>> import tempfile, uqdrape as ud
    >>> text = ud.derive_material("fge106hd", f"{tempfile.mkdtemp()}/fge.toml")
    >>> text.startswith("wrote")
    True
    """
    from .workflow.single_shot import derive_material as derive

    return derive(str(architecture), out, plot)


def fit_material(rig: PathLike, out: PathLike, plot: bool | PathLike | None = None) -> str:
    """Fit a material card to picture-frame or bias-extension shear tests (thesis ch. 3).

    Parameters
    ----------
    rig : str or os.PathLike
        The rig file (TOML) naming the test files and the rig's dimensions (the format:
        ``uqdrape.material.sheartest.reader``; the ``sheartests`` example holds one).
    out : str or os.PathLike
        The card to write (``.toml``); load it with :func:`load_material`.
    plot : bool or str or os.PathLike, optional
        Also draw the specimens, their normalised curves and the card's band: True
        beside the card, or a PNG path.

    Returns
    -------
    str
        A summary of each branch fitted, and warnings on lines of their own.

    Examples
    --------
    >>> import tempfile, uqdrape as ud
    >>> work = tempfile.mkdtemp()
    >>> rig = ud.copy_example("sheartests", work) / "pf-rig.toml"
    >>> ud.fit_material(rig, f"{work}/pf.toml").startswith("wrote")
    True
    """
    from .workflow.single_shot import fit_material as fit

    return fit(rig, out, plot)


def calibrate_fibre_angles(points: PathLike, out: PathLike, *, plot: bool | PathLike | None = None,
                           family: str = "auto", criterion: str = "aic", level: float = 0.9,
                           fibre1_deg: float = 45.0, posterior: bool = False, mm_per_px: float | None = None,
                           report: PathLike | None = None) -> str:
    """Calibrate a study's zero-angle field to fibre angles measured on a flat fabric.

    Fits a Gaussian field (mean, sd, correlation lengths along the fibres, a nugget) by
    restricted maximum likelihood for each correlation family and writes the study block
    ``[uncertainty.zero_angle]`` of the best, with profile-likelihood intervals.

    Parameters
    ----------
    points : str or os.PathLike
        A CSV ``x_mm,y_mm,angle_deg,fibre_set[,sd_deg]`` (the ``measurements`` example's
        ``fibre-angles.csv``), or an image of one fibre set's tows (with ``mm_per_px``).
    out : str or os.PathLike
        The study block to write (``.toml``).
    plot : bool or str or os.PathLike, optional
        Also write the calibration figure: True beside the block, or a PNG path.
    family : {"auto", "iid", "exponential", "squared_exponential"}, default "auto"
        The correlation family; "auto" keeps the one of least ``criterion``.
    criterion : {"aic", "bic"}, default "aic"
    level : float, default 0.9
        Confidence level of the intervals.
    fibre1_deg : float, default 45.0
        Nominal plan direction of fibre 1 (deg from x); fibre 2 at +90.
    posterior : bool, default False
        Also sample the parameters' posterior (needs ``uqdrape[calibrate]``).
    mm_per_px : float, optional
        ``points`` is an image at this scale (mm per pixel).
    report : str or os.PathLike, optional
        Also write the calibration report (``REPORT/index.html``).

    Returns
    -------
    str
        A summary of the fitted field (mean and sd in deg, lengths in mm).

    Examples
    --------
    >>> import tempfile, uqdrape as ud
    >>> work = tempfile.mkdtemp()
    >>> csv = ud.copy_example("measurements", work) / "fibre-angles.csv"
    >>> ud.calibrate_fibre_angles(csv, f"{work}/zero_angle.toml").startswith("wrote")
    True
    """
    from .workflow.calibrate import calibrate_fibre_angles as calibrate

    return calibrate(points, out, plot, family=family, criterion=criterion, level=level, fibre1_deg=fibre1_deg,
                     posterior=posterior, mm_per_px=mm_per_px, report=report, command="uqdrape.calibrate_fibre_angles")


def calibrate_drapes(parts: Sequence[PathLike], study: PathLike, parameters: Mapping[str, tuple[float, float]],
                     out: PathLike, *, report: PathLike | None = None, training_points: int | None = None,
                     realizations: int | None = None, measurement_sd: float = 0.1, level: float = 0.9,
                     scheduler: str | None = None, workers: int | None = None, progress: bool = True) -> str:
    """Calibrate study parameters to the shear measured on formed parts.

    The posterior of ``parameters`` (uniform priors) through a Gaussian-process emulator
    of the study's ensemble mean and sd at the measured points, over Latin-hypercube
    training points (ensemble runs), sampled with emcee (needs ``uqdrape[calibrate]``).

    Parameters
    ----------
    parts : sequence of str or os.PathLike
        Measured parts, one CSV each: ``distance_mm,shear_deg,quadrant_sign`` (the
        ``measurements`` example's ``part-*.csv``).
    study : str or os.PathLike
        The study whose parameters are calibrated.
    parameters : mapping of str to (float, float)
        Dotted study keys and their prior boxes, e.g.
        ``{"uncertainty.zero_angle.sd_deg": (0.5, 8.0)}`` (in the key's units).
    out : str or os.PathLike
        The calibrated study to write (``.toml``: the study at the posterior medians);
        the posterior sample goes beside it (``-posterior.nc``).
    report : str or os.PathLike, optional
        Also write the calibration report into this folder.
    training_points : int, optional
        Training points of the emulator, each an ensemble (default 10 per parameter).
    realizations : int, optional
        Drapes per training point (default: the study's).
    measurement_sd : float, default 0.1
        Sd of a measured shear's own error, deg.
    level : float, default 0.9
        Level of the intervals.
    scheduler, workers
        Where the training points' drapes run, as in :func:`run_study`.
    progress : bool, default True
        Show progress on stderr.

    Returns
    -------
    str
        The posterior medians and intervals and a posterior-predictive check.

    Examples
    --------
    >>> ud.calibrate_drapes(["part-1.csv", "part-2.csv"], "calibration-hemisphere.toml",
    ...                     {"uncertainty.zero_angle.sd_deg": (0.5, 8.0)}, "calibrated.toml")  # doctest: +SKIP
    """
    from .workflow.calibrate import calibrate_drapes as calibrate

    boxes = [f"{key}={float(low)!r}:{float(high)!r}" for key, (low, high) in parameters.items()]
    return calibrate([str(p) for p in parts], study, boxes, out, report=report, training_points=training_points,
                     realizations=realizations, measurement_sd=measurement_sd, level=level, scheduler=scheduler,
                     workers=workers, progress=progress, command="uqdrape.calibrate_drapes")
