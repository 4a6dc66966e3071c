"""``uqdrape calibrate``: measured fibre angles -> a calibrated ``[uncertainty.zero_angle]``
block (its figure and report); measured drapes -> the posterior of chosen study parameters
and the study at its medians. This is the step that opens the files, drapes the training
points (on the ensemble engine's schedulers) and writes the outputs; what the data,
likelihood and posterior are is ``uqdrape.calibration`` (``.drapes``, ``.parameters``), the
report pages ``uqdrape.report.calibration``. What stays here loads study files or drapes
(``study_at``, ``part_shear``, ``synthetic_parts``): ``calibration`` imports neither the
study layer nor the ensemble engine, so that ``report``, which imports it, never reaches
the engine."""

from __future__ import annotations

import dataclasses
import itertools
import time
from pathlib import Path

import dask
import numpy as np

from ..calibration import block_text, calibrate_points
from ..calibration.block import unidentified
from ..calibration.drapes import MAX_REALIZATIONS, DrapeCalibration, drape_posterior, posterior_dataset
from ..calibration.image import measured_points
from ..calibration.parameters import calibrated_study, parse_parameters
from ..errors import ParameterError
from ..ensemble import Progress, compute_tasks, drape_inputs, reach_scheduler, sampled_inputs
from ..experimental import ExperimentalPoints, read_experimental
from ..files import local_path, read_text, read_toml, toml_text, write_all, write_atomic, write_text_atomic
from ..schema import FORCE
from ..stats import shear_at_points
from ..study import load_study


def calibrate_fibre_angles(points_csv, out, plot=None, *, family: str = "auto", criterion: str = "aic",
                           level: float = 0.9, fibre1_deg: float = 45.0, command: str = "uqdrape calibrate",
                           posterior: bool = False, mm_per_px: float | None = None, window_px: float = 8.0,
                           fibre_set: int = 1, report=None) -> str:
    """Fit the γ0 field of the points in ``points_csv`` and write the study block ``out``
    (.toml), with the calibration figure if ``plot`` (True: beside the block, or a PNG
    path); the figure first, so a failed one leaves no block; ``posterior``: an emcee
    sample too (its intervals in the comments, sd_dof from it). An image (a suffix of
    calibration.image.IMAGE_SUFFIXES) is read as tows of ``fibre_set`` at scale
    ``mm_per_px`` through the structure tensor (window ``window_px``). Returns the summary."""
    out = local_path(out, "out")
    plot = local_path(plot, "plot") if isinstance(plot, (str, Path)) else plot
    report = None if report is None else local_path(report, "report")
    if out.suffix.lower() != ".toml":
        raise ParameterError("out", f"out must name the study block to write, a .toml path; got {str(out)!r}")
    points = measured_points(points_csv, mm_per_px, window_px=window_px, fibre_set=fibre_set)
    calibration = calibrate_points(points, fibre1_deg=fibre1_deg, family=family, criterion=criterion, level=level,
                                   posterior=posterior)
    png = page = None
    if plot:
        from ..report.calibration_figure import plot_calibration

        png = plot_calibration(calibration, out.with_suffix(".png") if plot is True else plot)
    block = block_text(calibration, command)
    if report is not None:
        from ..report.calibration import points_page

        page = points_page(calibration, report, block)
    write_text_atomic(out, block)
    fit = calibration.fit
    est = fit.estimates
    sd = est["sd_deg"]
    text = (f"wrote {out}: {fit.family} field (by {fit.criterion.upper()}) of {len(calibration.points)} points, "
            f"mean_deg {est['mean_deg'].value:.4g}, sd_deg {sd.value:.4g} [{sd.lower:.4g}, {sd.upper:.4g}]")
    if fit.family != "iid":
        text += ", length_mm [{:.4g}, {:.4g}]".format(est["length_1_mm"].value, est["length_2_mm"].value)
    text += f" ({100 * fit.level:g} % intervals in the block's comments)"
    return "\n".join([text, *[f"warning: {u}" for u in unidentified(calibration)],
                      *[f"wrote {p}" for p in (png, page) if p]])


# -- measured drapes -> study parameters (issue 25, second half) ----------------------------------

def study_at(study_path, values: dict, seed: int | None = None, realizations: int | None = None):
    """The study of ``study_path`` with each dotted key of ``values`` at its value
    (validated as if the file held it), its seed and realisations as given."""
    try:
        study = load_study(study_path, {key: float(v) for key, v in values.items()})
    except ValueError as err:
        raise ParameterError("parameters", f"at {', '.join(f'{k} = {v:.6g}' for k, v in values.items())}: "
                             f"{err}") from None
    return dataclasses.replace(study, seed=study.seed if seed is None else int(seed),
                               realizations=study.realizations if realizations is None else int(realizations))


def part_shear(study, realizations, distance_mm, quadrant_sign) -> np.ndarray:
    """Dask task: the shear (deg) of ``study``'s ``realizations`` at measured points, both
    line copies as draws (draw, point) (``uqdrape.stats.shear_at_points``)."""
    r = np.asarray(realizations)
    ds = drape_inputs(study, r, sampled_inputs(study, r))
    if FORCE in ds.dims:
        ds = ds.isel({FORCE: 0})
    return shear_at_points(ds, distance_mm, quadrant_sign).reshape(-1, len(distance_mm))


def _drape_batches(studies, realizations: int, distance, sign, *, scheduler, workers, progress, desc) -> list:
    """``part_shear`` of each study's realisations 0..realizations-1, chunk by chunk on the
    ensemble engine's schedulers; one (draw, point) array per study."""
    task = dask.delayed(part_shear, pure=False)
    tasks, owners, sizes = [], [], []
    for k, study in enumerate(studies):
        for a in range(0, realizations, study.chunk_size):
            b = min(a + study.chunk_size, realizations)
            tasks.append(task(study, np.arange(a, b), distance, sign))
            owners.append(k)
            sizes.append(b - a)
    reach_scheduler(scheduler)
    with Progress(sum(sizes), enabled=progress, desc=desc) as bar:
        parts = compute_tasks(tasks, sizes, scheduler, workers, bar)
    return [np.concatenate([p for p, o in zip(parts, owners) if o == k]) for k in range(len(studies))]


def synthetic_parts(study_path, values: dict, parts: int, distance_mm, *, seed: int, measurement_sd: float = 0.0,
                    scheduler="synchronous") -> list[ExperimentalPoints]:
    """``parts`` "measured" parts made by uqdrape: realisations of the study with its dotted
    keys at ``values`` (seed ``seed``), read at ``distance_mm`` on one line of each sign
    with Normal noise of sd ``measurement_sd`` (deg): a check of a calibration."""
    distance = np.tile(np.asarray(distance_mm, float), 2)
    sign = np.repeat([1.0, -1.0], len(distance_mm))
    study = study_at(study_path, values, seed, parts)
    (shear,) = _drape_batches([study], parts, distance, sign, scheduler=scheduler, workers=None, progress=False,
                              desc="synthetic parts")
    rng = np.random.default_rng(seed)
    nan = np.full(distance.size, np.nan)  # shear's rows 0..parts-1: line copy 0 of each realisation
    return [ExperimentalPoints(distance, shear[j] + measurement_sd * rng.standard_normal(distance.size), sign, nan,
                               f"synthetic part {j + 1}") for j in range(parts)]


def calibrate_parts(study_path, parts, params, *, training_points: int | None = None,
                    realizations: int | None = None, measurement_sd: float = 0.1, level: float = 0.9,
                    scheduler=None, workers=None, progress: bool = False, steps: int = 1500) -> DrapeCalibration:
    """The posterior of ``params`` (``calibration.parameters.Parameter``) given measured
    ``parts`` (``uqdrape.calibration.drapes.drape_posterior``): each training point draped
    as ``realizations`` (default the study's) with its own seed."""
    study = load_study(study_path)
    study.single_ply("a calibration from drapes")
    if study.is_sweep:
        raise ValueError(f"{study.path}: a calibration from drapes needs one blank-holder force level "
                         f"(the study sweeps {list(study.force_levels)} N)")
    r = study.realizations if realizations is None else realizations
    if not (isinstance(r, int) and 3 <= r <= MAX_REALIZATIONS):
        raise ParameterError("realizations", f"realizations must be an integer from 3 to {MAX_REALIZATIONS}, got {r!r}")
    keys = [p.key for p in params]
    for corner in itertools.product(*((p.lower, p.upper) for p in params)):  # a box the study refuses, before any drape
        study_at(study_path, dict(zip(keys, corner)))

    def drape(points, seeds, distance, sign):
        studies = [study_at(study_path, dict(zip(keys, x)), seed, r) for x, seed in zip(points, seeds)]
        return np.stack(_drape_batches(studies, r, distance, sign, scheduler=scheduler, workers=workers,
                                       progress=progress, desc=f"{study.name}: {len(points)} training points"))

    return drape_posterior(params, parts, drape, training_points=training_points, measurement_sd=measurement_sd,
                           level=level, seed=study.seed, steps=steps)


def calibrate_drapes(parts_csv, study_path, parameters, out, *, report=None,
                     training_points: int | None = None, realizations: int | None = None,
                     measurement_sd: float = 0.1, level: float = 0.9, scheduler=None, workers=None,
                     progress: bool = False, command: str = "uqdrape calibrate --drapes") -> str:
    """``uqdrape calibrate --drapes``: the posterior of ``parameters`` (``KEY=LOW:HIGH``
    texts) of the study ``study_path`` given the measured parts ``parts_csv`` (one CSV a
    part, ``uqdrape.experimental``'s format); writes ``out`` (.toml: the study at the
    posterior medians, validated where it is written), the sample beside it
    (``-posterior.nc``) and, with ``report`` (a folder), the calibration report. Returns
    the summary."""
    clock = time.perf_counter()
    out = local_path(out, "out")
    report = None if report is None else local_path(report, "report")
    if out.suffix.lower() != ".toml":
        raise ParameterError("out", f"out must name the calibrated study to write, a .toml path; got {str(out)!r}")
    study = load_study(study_path)
    study.single_ply("a calibration from drapes")
    params = parse_parameters(parameters, study)
    parts = [read_experimental(p) for p in parts_csv]
    write_atomic(out, lambda tmp: _valid_at(tmp, read_text(study_path, "study file"), out, study_path) and False)
    force_free = "process.blankholder_force_N" not in {p.key for p in params}
    for p in parts:
        forces = p.blankholder_force_N[np.isfinite(p.blankholder_force_N)]
        if force_free and forces.size and not np.allclose(forces, study.force_levels[0]):
            raise ValueError(f"{p.source}: measured at blankholder_force_N {forces[0]:g}, the study drapes at "
                             f"{study.force_levels[0]:g} N")
    cal = calibrate_parts(study_path, parts, params, training_points=training_points,
                          realizations=realizations, measurement_sd=measurement_sd, level=level,
                          scheduler=scheduler, workers=workers, progress=progress)
    lower, upper, fraction = cal.predictive_check()
    doc, comments = calibrated_study(read_toml(study_path, "study file"), cal, command, fraction)
    text = toml_text(doc, comments)

    def write_study(tmp):
        _valid_at(tmp, text, out, study_path)

    sample = out.with_name(out.stem + "-posterior.nc")
    writers = {out: write_study, sample: lambda tmp: posterior_dataset(cal, lower, upper).to_netcdf(tmp)}
    page = None
    if report is not None:
        from ..report.calibration import drapes_page

        page = drapes_page(cal, lower, upper, fraction, report, text, time.perf_counter() - clock)
    write_all(writers)
    text = [f"wrote {out} and {sample}: {len(parts)} part(s), {len(cal.runs.points)} training points x "
            f"{cal.runs.shear.shape[1] // 2} drapes"]
    text += [f"  {p.key}: median {np.median(cal.posterior.samples[p.key]):.4g}, {100 * level:g} % interval "
             f"[{cal.interval(p)[0]:.4g}, {cal.interval(p)[1]:.4g}]" for p in cal.params]
    text += [f"warning: {u}" for u in cal.unidentified()]
    text.append(f"posterior-predictive check: {100 * fraction:.0f} % of the measured points inside the "
                f"{100 * level:g} % band")
    return "\n".join(text + ([f"wrote {page}"] if page else []))


def _valid_at(tmp: Path, text: str, out: Path, study_path) -> bool:
    """Write the study ``text`` to ``tmp`` (beside ``out``) and validate it there: a study
    names its files relative to itself, so one written elsewhere may not find them."""
    tmp.write_text(text, encoding="utf-8")
    try:
        load_study(tmp)
    except ValueError as err:
        raise ParameterError("out", f"{out}: a study written there does not validate (it names its files relative to "
                         f"itself: write it beside {study_path}): {err}") from None
    return True
