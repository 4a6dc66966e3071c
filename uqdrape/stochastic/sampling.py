"""Sampling plans (standard uniforms) and per-realisation random streams.

Three sources of randomness, all derived from one study seed:

- a *plan*: an (N, d) array of standard uniforms for the d scalar factors (and, in a
  design, the KL mode variables of the fields), drawn in one piece by
  :func:`sample_uniforms` from ``SeedSequence(seed)`` itself;
- a *realisation stream*: realisation r draws the white noise of its exact fields from
  ``SeedSequence(seed, spawn_key=(r,))``, which is ``SeedSequence(seed).spawn(N)[r]``
  built directly. Realisation r's numbers therefore never depend on chunk size, worker
  count or N, and never overlap the plan's stream;
- a *randomised QMC* plan (``"rqmc"``, :func:`rqmc_uniforms`): K independent scramblings
  of one Sobol' point set of M = N / K points (a power of two); randomisation k scrambles
  from ``SeedSequence(seed, spawn_key=(RQMC_KEY, k))`` (a key of two words, so never a
  realisation's stream), and realisation r is point r mod M of randomisation r // M. A
  realisation depends on M, not on K, so a run extends by whole randomisations; the
  spread of the K randomisations' estimates is their error (Owen 1997; L'Ecuyer 2018).
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from .factors import normal

PLANS = ("monte_carlo", "latin_hypercube", "sobol")
#: A study's plans: those of :func:`sample_uniforms` and randomised QMC (:func:`rqmc_uniforms`).
RQMC = "rqmc"
STUDY_PLANS = (*PLANS, RQMC)
#: Plans whose realisation r is the same whatever the number of realisations N, so that a
#: run extends bitwise: Monte Carlo (every number from realisation r's own stream) and
#: randomised QMC with the same points per randomisation (more randomisations). A Latin
#: hypercube's strata and a Sobol' net's balance are those of N points: another N is
#: another design.
EXTENDABLE_PLANS = ("monte_carlo", RQMC)
#: First word of the seed-sequence key of an RQMC randomisation ("RQMC" in ASCII).
RQMC_KEY = 0x52514D43
#: Sensitivity designs (SALib's methods), and the sizes below which their indices cannot
#: rank factors. Sobol': scipy's Sobol' sequence is balanced only for powers of 2 (it
#: warns otherwise), and below 64 base samples the bootstrap intervals of S1/ST are
#: typically wider than +-0.2. Morris: fewer than 10 trajectories leave mu_star's
#: bootstrap interval meaningless (Campolongo et al. 2007 use 10-20).
METHODS = ("sobol", "morris")
SOBOL_MIN_BASE_SAMPLES = 64
MORRIS_MIN_TRAJECTORIES = 10

_STANDARD_NORMAL = normal(0.0, 1.0)


def _non_negative_int(name: str, value) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    return int(value)


def sample_uniforms(plan: str, n: int, d: int, seed: int) -> np.ndarray:
    """Standard uniforms of shape (n, d) from a sampling plan.

    ``"monte_carlo"``: independent uniforms (row r does not depend on n);
    ``"latin_hypercube"``: each of the n equal strata of every column is hit once;
    ``"sobol"``: scrambled Sobol' points, n must be a power of two (balance).
    """
    if plan not in PLANS:
        raise ParameterError("plan", f"plan must be one of {PLANS}, got {plan!r}")
    n, d = _non_negative_int("n", n), _non_negative_int("d", d)
    if n < 1:
        raise ParameterError("n", f"n (number of realisations) must be >= 1, got {n}")
    rng = np.random.default_rng(np.random.SeedSequence(_non_negative_int("seed", seed)))
    m = n.bit_length() - 1
    if plan == "sobol" and n != 1 << m:
        raise ParameterError(("plan", "n"), f"plan 'sobol' needs a power-of-two n for balance, got n={n} "
                                            f"(nearest: {1 << m}, {2 << m})")
    if d == 0:
        return np.empty((n, 0))
    if plan == "monte_carlo":
        return rng.random((n, d))
    from scipy.stats import qmc

    if plan == "latin_hypercube":
        return qmc.LatinHypercube(d, rng=rng).random(n)
    return qmc.Sobol(d, scramble=True, rng=rng).random_base2(m)


def extension_problem(sampling, held: int, n: int) -> str | None:
    """Why a run of ``held`` realisations under the plan ``sampling`` (a study's
    [sampling]) cannot be extended to ``n`` > held, in a few words; None if it can. (An
    rqmc run of the same study identity has the same points per randomisation, and n is
    a whole number of randomisations: ``rqmc_points``.)"""
    if sampling.plan not in EXTENDABLE_PLANS:
        return (f"sampling.plan = {sampling.plan!r} draws points that depend on study.realizations "
                f"(extendable: {', '.join(EXTENDABLE_PLANS)})")
    return None


def rqmc_points(n: int, randomizations) -> int:
    """Points per randomisation M = n / randomizations of an rqmc plan of n realisations;
    ParameterError unless K >= 2 (an error estimate needs two) divides n into a power of two."""
    if isinstance(randomizations, bool) or not isinstance(randomizations, (int, np.integer)) or randomizations < 2:
        raise ParameterError("randomizations", f"randomizations must be an integer >= 2 (the error estimate "
                                               f"is their spread), got {randomizations!r}")
    m, rest = divmod(_non_negative_int("n", n), int(randomizations))
    if rest or m < 1 or m & (m - 1):
        raise ParameterError(("n", "randomizations"),
                             f"plan 'rqmc' needs n = randomizations x M with M a power of two (a balanced "
                             f"Sobol' net per randomisation), got n={n}, randomizations={randomizations}")
    return m


def rqmc_uniforms(seed: int, randomization: int, points: int, d: int) -> np.ndarray:
    """The (points, d) standard uniforms of randomisation ``randomization`` of an rqmc
    plan: a Sobol' net of ``points`` (a power of two) points in d dimensions, scrambled by
    scipy's linear matrix scrambling and digital shift (Matousek 1998: the net stays
    balanced, every point is uniform) from its own seed sequence (module docstring)."""
    from scipy.stats import qmc

    if d > qmc.Sobol.MAXDIM:
        raise ParameterError("d", f"an rqmc plan of {d} variables needs a Sobol' sequence of {d} dimensions, "
                                  f"more than scipy's {qmc.Sobol.MAXDIM}")
    seq = np.random.SeedSequence(_non_negative_int("seed", seed),
                                 spawn_key=(RQMC_KEY, _non_negative_int("randomization", randomization)))
    return qmc.Sobol(d, scramble=True, rng=np.random.default_rng(seq)).random_base2(int(points).bit_length() - 1)


def uniforms_to_normals(u) -> np.ndarray:
    """Standard normals Φ⁻¹(u), e.g. the KL mode variables of a design's columns."""
    return _STANDARD_NORMAL.ppf(u)


def realization_rng(study_seed: int, r: int) -> np.random.Generator:
    """Random generator of realisation r: ``SeedSequence(study_seed).spawn(r + 1)[r]``, built directly."""
    seq = np.random.SeedSequence(_non_negative_int("study_seed", study_seed),
                                 spawn_key=(_non_negative_int("r", r),))
    return np.random.default_rng(seq)


def realization_normals(study_seed: int, realizations, sizes) -> tuple[np.ndarray, ...]:
    """White noise for the fields of a chunk of realisations.

    ``realizations``: the realisation indices of the chunk; ``sizes``: standard normals
    per realisation for each field input, in a fixed order (e.g. ``inp.n_variables``).
    Returns one array of shape (len(realizations), size) per entry of ``sizes``; row k
    comes from :func:`realization_rng` (study_seed, realizations[k]) alone.
    """
    sizes = [_non_negative_int("sizes entry", s) for s in sizes]
    out = [np.empty((len(realizations), s)) for s in sizes]
    for k, r in enumerate(realizations):
        rng = realization_rng(study_seed, r)
        for arr, s in zip(out, sizes):
            arr[k] = rng.standard_normal(s)
    return tuple(out)


def check_method(method) -> str:
    """``method`` if it is a sensitivity design of METHODS, else ValueError."""
    if method not in METHODS:
        raise ValueError(f"method={method!r} is not supported; valid: {', '.join(METHODS)}")
    return method


def check_base_samples(method: str, base_samples) -> int:
    """``base_samples`` as an int if it is a usable design size for ``method`` (Sobol': a
    power of 2 >= SOBOL_MIN_BASE_SAMPLES; Morris: >= MORRIS_MIN_TRAJECTORIES trajectories),
    else ValueError giving the minimum."""
    method = check_method(method)
    if isinstance(base_samples, bool) or not isinstance(base_samples, (int, np.integer)):
        raise ParameterError("base_samples", f"base_samples={base_samples!r} must be an integer")
    n = int(base_samples)
    if method == "sobol":
        if n < SOBOL_MIN_BASE_SAMPLES:
            raise ParameterError("base_samples", f"base_samples={n} is too small for Sobol': the minimum is "
                                                 f"{SOBOL_MIN_BASE_SAMPLES} (and it must be a power of 2)")
        if n & (n - 1):
            lower = 1 << (n.bit_length() - 1)
            raise ParameterError("base_samples",
                                 f"base_samples={n} must be a power of 2 for Sobol' (e.g. {lower} or {2 * lower})")
    elif n < MORRIS_MIN_TRAJECTORIES:
        raise ParameterError("base_samples", f"base_samples={n} is too small for Morris: the minimum is "
                                             f"{MORRIS_MIN_TRAJECTORIES} trajectories")
    return n
