"""``uqdrape calibrate``: measured fibre angles -> a calibrated ``[uncertainty.zero_angle]``
block (its figure and report); measured drapes -> the posterior of chosen study parameters
and the study at its medians (the training points' ensembles draped here, on the ensemble engine's
schedulers; the emulator and likelihood in ``uqdrape.calibration.drapes``)."""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from dataclasses import dataclass
from pathlib import Path

from datetime import date

import dask
import numpy as np
import xarray as xr

from .._version import __version__
from ..calibration import block_text, calibrate_points, read_points
from ..calibration.block import sd_dof, unidentified
from ..errors import ParameterError
from ..calibration.drapes import TrainingRuns, Parts, PartsLikelihood, predictive_bands, sample_posterior
from ..calibration.emulator import Emulator, latin_hypercube
from ..calibration.fit import Estimate
from ..ensemble import Progress, compute_tasks, drape_inputs, reach_scheduler, sampled_inputs
from ..experimental import ExperimentalPoints, read_experimental
from ..files import (is_number, local_path, read_text, read_toml, toml_text, write_all, write_atomic,
                     write_text_atomic)
from ..schema import FORCE
from ..stats import shear_at_points
from ..study import load_study


def _image_points(path: Path, mm_per_px, window_px: float, fibre_set: int):
    """The points of an image file, or None for a CSV."""
    from ..calibration.image import IMAGE_SUFFIXES, image_points, read_image

    if path.suffix.lower() not in IMAGE_SUFFIXES:
        if mm_per_px is not None:
            raise ParameterError("mm_per_px", f"mm_per_px is the scale of an image ({', '.join(IMAGE_SUFFIXES)}); "
                                 f"{path} is read as a points CSV")
        return None
    if mm_per_px is None:
        raise ParameterError("mm_per_px", f"{path} is an image: give its scale, mm_per_px (mm per pixel, > 0)")
    return image_points(read_image(path), mm_per_px, window_px=window_px, fibre_set=fibre_set, source=str(path))


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
    points = _image_points(Path(points_csv), mm_per_px, window_px, fibre_set)
    calibration = calibrate_points(points if points is not None else read_points(points_csv), fibre1_deg=fibre1_deg, family=family,
                                   criterion=criterion, level=level, posterior=posterior)
    png = page = None
    if plot:
        from ..report.calibration_figure import plot_calibration

        png = plot_calibration(calibration, out.with_suffix(".png") if plot is True else plot)
    block = block_text(calibration, command)
    if report is not None:
        page = _points_report(calibration, report, block)
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

#: Training points of the emulator per calibrated parameter when ``training_points`` is not given.
TRAINING_POINTS_PER_PARAMETER = 10
#: Most training points (each an ensemble; the emulator's GPs factor an n x n matrix per
#: measured point) and drapes per training point of a calibration.
MAX_TRAINING_POINTS = 1000
MAX_REALIZATIONS = 10000


@dataclass(frozen=True)
class Parameter:
    """A calibrated study parameter: its dotted study key and uniform prior box (its units)."""

    key: str
    lower: float
    upper: float


def parse_parameters(texts, study) -> list[Parameter]:
    """``KEY=LOW:HIGH`` texts (``--parameter``) as Parameters: KEY a number of ``study``
    (defaults filled, e.g. ``process.friction``, ``uncertainty.zero_angle.sd_deg``)."""
    params = []
    doc = study.to_dict()
    for text in texts:
        key, _, box = text.partition("=")
        lo, _, hi = box.partition(":")
        value = doc
        for name in key.split("."):
            value = value.get(name) if isinstance(value, dict) else None
        if not is_number(value):
            raise ParameterError("parameters", f"{text!r}: {key!r} is not a number of {study.path} (with defaults "
                             "filled); give a dotted study key such as process.friction or "
                             "uncertainty.zero_angle.sd_deg, as KEY=LOW:HIGH (a key without a default, "
                             "such as fabric.imbalance_Nm, must be set in the study file first)")
        try:
            lower, upper = float(lo), float(hi)
        except ValueError:
            lower = upper = math.nan
        if not (math.isfinite(lower) and math.isfinite(upper) and lower < upper):
            raise ParameterError("parameters", f"{text!r}: the prior box must be LOW:HIGH, two numbers with "
                                 "LOW < HIGH")
        if key in (p.key for p in params):
            raise ParameterError("parameters", f"{key} is given twice")
        params.append(Parameter(key, lower, upper))
    if not params:
        raise ParameterError("parameters", "a calibration from drapes needs at least one parameter KEY=LOW:HIGH")
    return params


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
    bar = Progress(sum(sizes), enabled=progress, desc=desc)
    try:
        parts = compute_tasks(tasks, sizes, scheduler, workers, bar)
    finally:
        bar.close()
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


def _union(parts) -> tuple[np.ndarray, np.ndarray, Parts]:
    """The measured points of all parts (distance, sign) and each part's index into them."""
    keys = sorted({(s, round(float(d), 6)) for p in parts for d, s in zip(p.distance_mm, p.quadrant_sign)})
    where = {k: n for n, k in enumerate(keys)}
    index = []
    for p in parts:
        idx = [where[(s, round(float(d), 6))] for d, s in zip(p.distance_mm, p.quadrant_sign)]
        if len(set(idx)) < len(idx):
            raise ValueError(f"{p.source}: a point is measured twice (same distance_mm and quadrant_sign); a part "
                             "gives one line of each sign")
        index.append(np.array(idx))
    sign, distance = (np.array(c, float) for c in zip(*keys))
    return distance, sign, index


@dataclass
class DrapeCalibration:
    """A calibration from measured drapes: the parameters, the parts, the draped training points,
    the likelihood (emulator inside), the posterior and its ``level``."""

    params: list
    parts: list
    runs: TrainingRuns
    likelihood: PartsLikelihood
    posterior: object
    level: float
    distance_mm: np.ndarray
    quadrant_sign: np.ndarray

    def interval(self, param) -> tuple[float, float]:
        return self.posterior.interval(param.key, self.level)

    def unidentified(self) -> list[str]:
        """A sentence per parameter whose posterior reaches its prior bound."""
        out = []
        for p in self.params:
            ends = self.posterior.at_bounds(p.key, p.lower, p.upper)
            if ends:
                lo, hi = self.interval(p)
                out.append(f"{p.key} is not identified by the data: its posterior reaches the prior bound "
                           f"{' and '.join(f'{b:g}' for b in ends)} ({100 * self.level:g} % interval "
                           f"[{lo:.4g}, {hi:.4g}] is the prior's, not the measurements'); widen its prior box or "
                           "measure more")
        return out


def calibrate_parts(study_path, parts, params, *, training_points: int | None = None,
                    realizations: int | None = None, measurement_sd: float = 0.1, level: float = 0.9,
                    scheduler=None, workers=None, progress: bool = False, steps: int = 1500) -> DrapeCalibration:
    """The posterior of ``params`` given measured ``parts`` (``uqdrape.calibration.drapes``):
    ``training_points`` Latin-hypercube points (default 10 per parameter) in the prior
    box, each draped as ``realizations`` (default the study's) with its own seed, the
    emulator over them and emcee; then a second round of half as many points drawn from
    that posterior, the emulator refitted on all and the posterior sampled again."""
    study = load_study(study_path)
    if study.is_sweep:
        raise ValueError(f"{study.path}: a calibration from drapes needs one blank-holder force level "
                         f"(the study sweeps {list(study.force_levels)} N)")
    if not 0 <= measurement_sd <= 90:
        raise ParameterError("measurement_sd", f"measurement_sd must be from 0 to 90 (deg), got {measurement_sd!r}")
    distance, sign, index = _union(parts)
    n = TRAINING_POINTS_PER_PARAMETER * len(params) if training_points is None else training_points
    r = study.realizations if realizations is None else realizations
    for name, value, least, most in (("training_points", n, len(params) + 2, MAX_TRAINING_POINTS),
                                     ("realizations", r, 3, MAX_REALIZATIONS)):
        if not (isinstance(value, int) and least <= value <= most):
            raise ParameterError(name, f"{name} must be an integer from {least} to {most}, got {value!r}")
    lower, upper = np.array([p.lower for p in params]), np.array([p.upper for p in params])
    keys = [p.key for p in params]
    for corner in itertools.product(*zip(lower, upper)):  # a box the study refuses, before any drape
        study_at(study_path, dict(zip(keys, corner)))
    points = latin_hypercube(lower, upper, n, study.seed)
    runs = None
    for _ in range(2):
        studies = [study_at(study_path, dict(zip(keys, x)), study.seed + 1 + k + (0 if runs is None else len(runs.points)),
                            r) for k, x in enumerate(points)]
        shear = np.stack(_drape_batches(studies, r, distance, sign, scheduler=scheduler, workers=workers,
                                        progress=progress, desc=f"{study.name}: {len(points)} training points"))
        runs = TrainingRuns(points, shear) if runs is None else TrainingRuns(np.vstack([runs.points, points]),
                                                                         np.concatenate([runs.shear, shear]))
        mean, log_sd, var_mean, var_log_sd = runs.statistics()
        emulator = Emulator(runs.points, np.hstack([mean, log_sd]), np.hstack([var_mean, var_log_sd]), lower, upper,
                            seed=study.seed)
        likelihood = PartsLikelihood(emulator, runs.correlation(),
                                     Parts(tuple(index), tuple(p.shear_deg for p in parts), measurement_sd),
                                     lower, upper)
        posterior = sample_posterior(likelihood, keys, steps=steps, seed=study.seed)
        # second round: half as many training points again, drawn from the first posterior, so
        # the emulator is refined where the posterior lies (its error there is what matters)
        draws = np.column_stack([posterior.samples[k] for k in keys])
        points = draws[np.random.default_rng(study.seed).choice(len(draws), size=max(n // 2, 2), replace=False)]
    return DrapeCalibration(params, parts, runs, likelihood, posterior, level, distance, sign)


def _calibrated_study(study_path, cal: DrapeCalibration, command: str, fraction: float) -> tuple[dict, str]:
    """The study file's own document with each parameter at its posterior median (and, for
    the zero-angle sd, sd_dof from its interval), renamed "-calibrated"; the fit as comments."""
    doc = read_toml(study_path, "study file")
    name = f"{doc['study']['name']}-calibrated"
    overrides = {"study.name": name}
    if "directory" in doc.get("output", {}):
        overrides["output.directory"] = str(Path(doc["output"]["directory"]).parent / name)
    level = 100 * cal.level
    post = cal.posterior
    lines = [f"{name}: calibrated by `{command}` (uqdrape {__version__}, {date.today().isoformat()})",
             f"from {len(cal.parts)} measured part(s): " + ", ".join(Path(p.source).name for p in cal.parts)
             + f"; {len(cal.distance_mm)} distinct points, measurement sd {cal.likelihood.parts.measurement_sd:g} deg",
             f"emulator: a GP per point's ensemble mean and log sd over {len(cal.runs.points)} training points of "
             f"{cal.runs.shear.shape[1] // 2} realisations (uqdrape.calibration.drapes)",
             f"posterior (emcee, {len(next(iter(post.samples.values())))} draws, acceptance {post.acceptance:.2f}, "
             f"{post.seconds:.1f} s): median and {level:g} % interval, uniform prior in the box"]
    for p in cal.params:
        lo, hi = cal.interval(p)
        value = float(f"{np.median(post.samples[p.key]):.4g}")
        overrides[p.key] = value
        lines.append(f"  {p.key} = {value:.4g}  [{lo:.4g}, {hi:.4g}]  prior [{p.lower:g}, {p.upper:g}]  "
                     f"autocorrelation {post.autocorrelation[p.key]:.0f} steps")
        if p.key == "uncertainty.zero_angle.sd_deg":
            m = None if post.at_bounds(p.key, p.lower, p.upper) else sd_dof(Estimate(value, lo, hi), cal.level)
            if m is not None:
                overrides["uncertainty.zero_angle.sd_dof"] = float(f"{m:.4g}")
                lines.append(f"  sd_dof = {m:.4g}: the sd's interval as a scaled-inverse-chi-square one "
                             "(a hierarchical ensemble; delete it for a fixed sd)")
    lines += [f"WARNING: {u}" for u in cal.unidentified()]
    lines.append(f"posterior-predictive check: {100 * fraction:.0f} % of the measured points inside the "
                 f"{level:g} % predictive band")
    for key, value in overrides.items():
        *tables, leaf = key.split(".")
        table = doc
        for t in tables:
            table = table.setdefault(t, {})
        table[leaf] = value
    return doc, "\n".join(lines)


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
    lower, upper = predictive_bands(cal.likelihood, cal.posterior, level)
    inside = [(y >= lower[i]) & (y <= upper[i]) for i, y in zip(cal.likelihood.parts.index, cal.likelihood.parts.shear)]
    fraction = float(np.concatenate(inside).mean())
    doc, comments = _calibrated_study(study_path, cal, command, fraction)
    text = toml_text(doc, comments)

    def write_study(tmp):
        _valid_at(tmp, text, out, study_path)

    sample = out.with_name(out.stem + "-posterior.nc")
    writers = {out: write_study, sample: lambda tmp: posterior_dataset(cal, lower, upper).to_netcdf(tmp)}
    page = None
    if report is not None:
        page = _drape_report(cal, lower, upper, fraction, report, text, time.perf_counter() - clock)
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


def posterior_dataset(cal: DrapeCalibration, lower, upper) -> xr.Dataset:
    """The posterior sample, the draped training points and the measured parts as one Dataset."""
    names = [p.key for p in cal.params]
    mean, log_sd, _, _ = cal.runs.statistics()
    measured = np.full((len(cal.parts), len(cal.distance_mm)), np.nan)
    for j, (idx, y) in enumerate(zip(cal.likelihood.parts.index, cal.likelihood.parts.shear)):
        measured[j, idx] = y
    deg = {"units": "degree"}
    return xr.Dataset(
        {"posterior": (("draw", "parameter"), np.column_stack([cal.posterior.samples[n] for n in names]),
                       {"long_name": "posterior sample (emcee), in each parameter's study units"}),
         "prior_lower": ("parameter", [p.lower for p in cal.params]),
         "prior_upper": ("parameter", [p.upper for p in cal.params]),
         "training_points": (("training_point", "parameter"), cal.runs.points),
         "training_mean": (("training_point", "point"), mean, {**deg, "long_name": "ensemble mean shear"}),
         "training_sd": (("training_point", "point"), np.exp(log_sd), {**deg, "long_name": "ensemble shear sd"}),
         "measured": (("part", "point"), measured, {**deg, "long_name": "measured shear (NaN: not measured)"}),
         "predictive_lower": ("point", lower, deg), "predictive_upper": ("point", upper, deg),
         "distance": ("point", cal.distance_mm, {"units": "mm", "long_name": "distance from the crossover"}),
         "quadrant_sign": ("point", cal.quadrant_sign)},
        coords={"parameter": names, "part": [Path(p.source).name for p in cal.parts]},
        attrs={"level": cal.level, "acceptance": cal.posterior.acceptance, "sampler_seconds": cal.posterior.seconds})


def _drape_report(cal: DrapeCalibration, lower, upper, fraction: float, folder: Path, written: str,
                  seconds: float) -> Path:
    """The calibration report of a calibration from measured drapes (``report.calibration``)."""
    from ..report.calibration_figure import plot_drape_posterior, plot_drape_predictive
    from ..report.calibration import calibration_page

    data = posterior_dataset(cal, lower, upper)
    level = 100 * cal.level
    posterior = plot_drape_posterior(cal.posterior.samples, data["prior_lower"].values, data["prior_upper"].values,
                                     cal.level, folder / "posterior.png")
    check = plot_drape_predictive(cal.distance_mm, cal.quadrant_sign, data["measured"].values, lower, upper,
                                  cal.level, list(data["part"].values), folder / "predictive.png")
    rows = [("measured parts", ", ".join(str(p) for p in data["part"].values)),
            ("distinct measured points", str(len(cal.distance_mm))),
            ("measurement sd", f"{cal.likelihood.parts.measurement_sd:g} deg"),
            ("training points (Latin hypercube)", f"{len(cal.runs.points)} points x {cal.runs.shear.shape[1] // 2} drapes"),
            *[(p.key, f"{np.median(cal.posterior.samples[p.key]):.4g} [{cal.interval(p)[0]:.4g}, "
                      f"{cal.interval(p)[1]:.4g}] ({level:g} %), prior [{p.lower:g}, {p.upper:g}]")
              for p in cal.params],
            ("sampler", f"emcee, acceptance {cal.posterior.acceptance:.2f}, {cal.posterior.seconds:.1f} s"),
            ("posterior-predictive check", f"{100 * fraction:.0f} % of the measured points inside the {level:g} % band")]
    figures = [(posterior, f"Posterior of {', '.join(p.key for p in cal.params)}: marginals with median and "
                           f"{level:g} % interval, pairs below"),
               (check, f"Measured shear against the {level:g} % posterior-predictive band of a new part")]
    return calibration_page(folder, "Calibration from measured drapes", rows, figures, written, cal.unidentified(),
                            seconds=seconds)


def _points_report(calibration, folder: Path, written: str) -> Path:
    """The calibration report of measured fibre angles (``report.calibration``): the
    calibration figure (points, fitted field, leave-one-out predictive check, profiles)
    and, if sampled, the posterior."""
    from ..report.calibration_figure import loo_check, plot_calibration, plot_drape_posterior
    from ..calibration.posterior import prior_box
    from ..report.calibration import calibration_page

    fit, post = calibration.fit, calibration.posterior
    level = 100 * fit.level
    figures = [(plot_calibration(calibration, folder / "calibration.png"),
                f"Measured points (γ0), the fitted field, each point against its {level:g} % band predicted from "
                "the others (the count inside in the title), the profile likelihoods and the families' criteria")]
    rows = [("measured points", f"{len(calibration.points)} ({Path(calibration.points.source).name})"),
            ("family", f"{fit.family} (least {fit.criterion.upper()})"),
            *[(name, f"{e.value:.4g} [{e.lower:.4g}, {e.upper:.4g}] ({level:g} % profile)")
              for name, e in fit.estimates.items() if name != "nugget_deg"]]
    inside = loo_check(calibration)[2]
    rows.append(("predictive check", f"{inside.sum()} of {inside.size} points ({100 * inside.mean():.0f} %) inside the "
                                     f"{level:g} % band predicted from the others"))
    if post is not None:
        box = prior_box(fit)
        logs = {name: np.log10(draws) for name, draws in post.samples.items()}
        figures.append((plot_drape_posterior({f"log10 {n}": v for n, v in logs.items()},
                                             [np.log10(box[n][0]) for n in logs], [np.log10(box[n][1]) for n in logs],
                                             fit.level, folder / "posterior.png"),
                        "Posterior (emcee) of the field's parameters, log10 on the prior's whole box"))
        rows += [(f"{name}, posterior", f"[{lo:.4g}, {hi:.4g}] ({level:g} %)")
                 for name in post.samples for lo, hi in [post.interval(name, fit.level)]]
    return calibration_page(folder, "Fibre-angle calibration", rows, figures, written, unidentified(calibration),
                            seconds=None if post is None else post.seconds)
