"""Per-realisation solver inputs of a study, from standard random variables.

Every uncertain input is a function of *standard variables*: standard normals drive the
random fields (spacing: segment lengths in mm; zero angle, or stitch pre-strain mapped
through the card's architecture: gamma0 per cell in degrees)
and standard uniforms drive the scalar factors (through ``Factor.ppf``, in the factor's
own unit). Two sources of standard variables share one map (:func:`_inputs`):

- :func:`sampled_inputs` -- the study's own ensemble. Realisation r's field noise comes
  from its own stream (``realization_normals(seed, [r], ...)``, exact sampling). Its
  factor uniforms come from the sampling plan: ``monte_carlo`` draws them from the same
  stream right after the field noise (u = Phi(z) of further normals of that stream);
  ``latin_hypercube`` / ``sobol`` take row r of the global sample matrix
  ``sample_uniforms(plan, N, d, seed)`` (N = study realisations, d = number of
  factors; cheap, recomputed wherever needed). Fields stay exact Monte Carlo under every
  plan. Under ``rqmc`` every standard variable comes from a scrambled Sobol' point instead:
  realisation r is point r mod M of randomisation r // M (``rqmc_uniforms``), its
  columns those of :func:`sample_columns` (factor uniforms, then the fields' truncated
  KL modes as Phi^-1(u), keeping ``kl_retained`` of each field's variance), mapped by
  :func:`inputs_from_rows`. Either way realisation r's numbers never depend on the chunk
  it is in or on which worker runs it.
- :func:`inputs_from_rows` -- an explicit sample matrix (e.g. a sensitivity sample),
  columns as named by :func:`sample_columns`: factor uniforms first, then each field's
  truncated Karhunen-Loeve mode variables (standard normals), ``name[k]``.

A zero-angle field with ``sd_dof`` (a hierarchical ensemble) also draws each
realisation's sd, :func:`realization_sd_deg`: one more standard normal z of the
realisation's stream, after all the others (so the other numbers stay as without it),
mapped to sd_r = sd_deg √(m / χ²_m(Φ(z))), m = sd_dof; the field is then
γ0 = μ0 + sd_r ξ_c. A correlated zero-angle field with ``length_log_sd`` = s draws its
correlation lengths per realisation likewise, :func:`realization_length_mm`: one more
normal z after the sd's (so every other number, the sd's included, stays as without it),
both lengths L_r = L exp(s z), so the study's L is their median (and geometric mean); the
field of realisation r is sampled exactly from a field rebuilt for L_r (two 2n x 2n
eigendecompositions per realisation, eigenvector signs matched to the study's field so
that the same noise gives a nearby field for a nearby length; ξ_c keeps its values).
Only :func:`sampled_inputs` does this (validation refuses both keys with rqmc and
sensitivity samples).

Returned inputs are a dict of arrays with a leading realisation axis: ``seg_i``
(R, 2n, 2n+1) and ``seg_j`` (R, 2n+1, 2n) in mm if spacing varies, ``gamma0``
(R, 2n, 2n) in degrees if the zero angle varies, and one (R,) array per scalar factor
named as in the study (``friction``, ``orientation``, ``crossover_x``, ...).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..stochastic import realization_normals, sample_uniforms, uniforms_to_normals
from ..stochastic.sampling import RQMC, rqmc_points, rqmc_uniforms


def _realizations(study, realizations) -> np.ndarray:
    """Realisation indices as an int array, each in [0, study.realizations)."""
    r = np.asarray(realizations)
    if r.ndim != 1 or r.size == 0 or not np.issubdtype(r.dtype, np.integer):
        raise ValueError(f"realizations must be a non-empty 1-D sequence of integers, got {realizations!r}")
    bad = r[(r < 0) | (r >= study.realizations)]
    if bad.size:
        raise ValueError(f"realization index {int(bad[0])} is outside the study's 0..{study.realizations - 1}")
    return r.astype(np.int64)


def _field_inputs(study, kl: bool) -> dict:
    """The study's random-field input maps by name (exact, or truncated KL for sample rows)."""
    out = {}
    for name, spec in study.uncertainty.fields.items():
        inp = spec.build_input(study.solver.rings, study.fabric.spacing_mm)
        out[name] = inp.kl(spec.kl_retained) if kl else inp
    return out


def _inputs(study, fields: dict, xi: dict, u: np.ndarray) -> dict:
    """Solver inputs from field standard normals ``xi[name]`` (R, n_variables) and factor
    uniforms ``u`` (R, d), columns in the order of ``study.uncertainty.factors``."""
    out = {}
    if "spacing" in fields:
        out["seg_i"], out["seg_j"] = fields["spacing"](xi["spacing"])
    for name in ("zero_angle", "stitch_prestrain"):  # the study allows one of them
        if name in fields:
            out["gamma0"] = fields[name](xi[name])
    for k, (name, factor) in enumerate(study.uncertainty.factors.items()):
        out[name] = factor.ppf(u[:, k])
    return out


def _hierarchical(study):
    """The zero-angle field whose sd or lengths are drawn per realisation, or None."""
    field = study.uncertainty.fields.get("zero_angle")
    drawn = field is not None and (field.sd_dof is not None or field.length_log_sd is not None)
    return field if drawn else None


def _normals(study, r, fields) -> tuple:
    """Each realisation's stream: the fields' noise, the factors' (monte_carlo), then the
    hierarchical sd's one normal, then the hierarchical lengths' one normal."""
    d = len(study.uncertainty.factors)
    sizes = [inp.n_variables for inp in fields.values()] + ([d] if study.sampling.plan == "monte_carlo" else [])
    field = _hierarchical(study)
    if field is not None:
        sizes += [1] * ((field.sd_dof is not None) + (field.length_log_sd is not None))
    return realization_normals(study.seed, r, sizes)


def _drawn(field, normals) -> tuple:
    """(sd_r in deg or None, (R, 2) lengths L_r in mm or None) of a hierarchical field from
    the tail of its realisations' ``normals``."""
    tail = iter(normals[::-1])
    lengths = None if field.length_log_sd is None else (
        np.asarray(field.length_mm) * np.exp(field.length_log_sd * next(tail)[:, :1]))
    sd = None if field.sd_dof is None else _sd_from_normal(field, next(tail)[:, 0])
    return sd, lengths


def _sd_from_normal(field, z) -> np.ndarray:
    """sd_r = sd_deg √(m / χ²_m) with χ²_m its Φ(z) quantile (deg)."""
    from scipy.special import ndtr
    from scipy.stats import chi2

    m = field.sd_dof
    return field.params["sd_deg"] * np.sqrt(m / chi2.ppf(ndtr(np.asarray(z, dtype=float)), m))


def _drawn_or_fixed(study, realizations, which: int, fixed) -> np.ndarray:
    """Entry ``which`` of :func:`_drawn` for the given realisations, or ``fixed`` per
    realisation where the study does not draw it."""
    r = _realizations(study, realizations)
    field = _hierarchical(study)
    value = None if field is None else _drawn(field, _normals(study, r, _field_inputs(study, kl=False)))[which]
    return np.array([fixed] * r.size, dtype=float) if value is None else value


def realization_sd_deg(study, realizations) -> np.ndarray:
    """The zero-angle sd (deg) of each given realisation: drawn as in the module
    docstring under ``sd_dof``, else the study's sd_deg (or 0 without a zero-angle field)."""
    plain = study.uncertainty.fields.get("zero_angle")
    return _drawn_or_fixed(study, realizations, 0, plain.params["sd_deg"] if plain is not None else 0.0)


def realization_length_mm(study, realizations) -> np.ndarray:
    """The zero-angle field's correlation lengths (R, 2) in mm (along fibre 1, fibre 2) of
    each given realisation: drawn as in the module docstring under ``length_log_sd``, else
    the study's length_mm (NaN for an iid field or none)."""
    plain = study.uncertainty.fields.get("zero_angle")
    fixed = plain.length_mm if plain is not None and plain.length_mm is not None else (np.nan, np.nan)
    return _drawn_or_fixed(study, realizations, 1, fixed)


def sampled_inputs(study, realizations) -> dict:
    """Solver inputs of the given realisation indices of the study's ensemble."""
    r = _realizations(study, realizations)
    if study.sampling.plan == RQMC:
        return inputs_from_rows(study, rqmc_rows(study, r))
    fields = _field_inputs(study, kl=False)
    d = len(study.uncertainty.factors)
    normals = _normals(study, r, fields)
    xi = dict(zip(fields, normals))
    if study.sampling.plan == "monte_carlo" and d == 0:
        u = np.empty((r.size, 0))  # no factor: nothing for Φ (scipy.special) to map
    elif study.sampling.plan == "monte_carlo":
        from scipy.special import ndtr

        u = ndtr(normals[len(fields)])
    else:
        u = sample_uniforms(study.sampling.plan, study.realizations, d, study.seed)[r]
    field = _hierarchical(study)
    if field is not None:
        unit = fields["zero_angle"]
        sd, lengths = _drawn(field, normals)
        fields = dict(fields, zero_angle=lambda z: _zero_angle(study, field, unit, z, sd, lengths))
    return _inputs(study, fields, xi, u)


def _zero_angle(study, field, inp, xi, sd, lengths) -> np.ndarray:
    """γ0 (deg) of rows ``xi`` of a hierarchical zero-angle field: each row's field rebuilt
    for its drawn lengths (exact sampling) and, the field being linear in its sd, rescaled
    to its drawn sd."""
    if lengths is None:
        return _scaled(inp, xi, sd)
    rows = [dataclasses.replace(field, length_mm=tuple(L)).build_input(study.solver.rings, study.fabric.spacing_mm)
            .aligned_to(inp) for L in lengths]
    return np.concatenate([f(xi[k:k + 1]) if sd is None else _scaled(f, xi[k:k + 1], sd[k:k + 1])
                           for k, f in enumerate(rows)])


def _scaled(inp, xi, sd) -> np.ndarray:
    """γ0 = μ0 + sd_r ξ (deg) of a ZeroAngleInput ``inp`` with a sd per row of ``xi``."""
    mean, sd0 = inp.mean_deg, inp.sd_deg
    z = (inp(xi) - mean) / sd0 if sd0 > 0 else np.zeros_like(inp(xi))
    gamma0 = mean + sd.reshape((-1,) + (1,) * (z.ndim - 1)) * z
    bad = np.flatnonzero(np.any(np.abs(gamma0) >= 90.0, axis=tuple(range(1, z.ndim))))
    if bad.size:
        raise ValueError(f"zero angle mean_deg={mean:g} with a realisation's sd_deg={sd[bad[0]]:g} (drawn by sd_dof) "
                         "gave |gamma0| >= 90 degrees; use a larger sd_dof or a smaller sd_deg")
    return gamma0


def rqmc_rows(study, realizations) -> np.ndarray:
    """Rows of the study's rqmc plan for the given realisation indices, in the standard
    variables of :func:`sample_columns` (uniforms for the factors, normals for the KL
    modes). Each randomisation's points are drawn once per call."""
    r = np.asarray(realizations, dtype=np.int64)
    points = rqmc_points(study.realizations, study.sampling.randomizations)
    d_factors, d = len(study.uncertainty.factors), len(sample_columns(study))
    X = np.empty((r.size, d))
    for k in np.unique(r // points):
        rows = np.flatnonzero(r // points == k)
        X[rows] = rqmc_uniforms(study.seed, int(k), points, d)[r[rows] % points]
    X[:, d_factors:] = uniforms_to_normals(X[:, d_factors:])
    return X


def sample_columns(study) -> list[str]:
    """Column names of a sample matrix for :func:`inputs_from_rows`: the scalar factors
    (standard uniforms), then ``field[k]`` for each field's KL modes (standard normals),
    fields in the order ``spacing``, ``zero_angle``, ``stitch_prestrain`` (as uqdrape.sensitivity
    names them)."""
    names = list(study.uncertainty.factors)
    for name, inp in _field_inputs(study, kl=True).items():
        names += [f"{name}[{k}]" for k in range(inp.n_variables)]
    return names


def inputs_from_rows(study, X) -> dict:
    """Solver inputs of the rows of a sample matrix X (R, len(sample_columns(study)))
    of standard variables; row k becomes realisation k of the result."""
    X = np.asarray(X, dtype=float)
    names = sample_columns(study)
    if X.ndim != 2 or X.shape[0] == 0 or X.shape[1] != len(names):
        raise ValueError(f"X must have shape (R >= 1, {len(names)}) with columns {names}, got shape {X.shape}")
    d = len(study.uncertainty.factors)
    u = X[:, :d]
    if np.any(~((u >= 0.0) & (u <= 1.0))):
        raise ValueError(f"X columns {names[:d]} are standard uniforms and must lie in [0, 1]")
    if not np.all(np.isfinite(X[:, d:])):
        raise ValueError(f"X columns {names[d:]} are standard normals and must be finite")
    fields = _field_inputs(study, kl=True)
    cuts = np.cumsum([d] + [inp.n_variables for inp in fields.values()])
    xi = dict(zip(fields, np.split(X, cuts[:-1], axis=1)[1:]))
    return _inputs(study, fields, xi, u)
