"""A study's sensitivity sample: its SALib problem in the ensemble's standard variables
and the seeded sample matrix of a method (see ``uqdrape.workflow`` for how it is run).

Sobol' indices are unchanged by a monotone map of each input, and the Morris screening
order is too, so the problem is posed in the standard variables the ensemble consumes
(``uqdrape.ensemble.sample_columns``):

- a random field is one group: its truncated Karhunen-Loeve standard normals ("norm"
  [0, 1]), the modes keeping ``kl_retained`` of the variance;
- a scalar factor is its own group, coded as a standard uniform u ("unif" [0, 1]) when
  its distribution is bounded (uniform, truncnormal), and as a standard normal
  z = Phi^-1(u) ("norm" [0, 1]) when unbounded (normal, lognormal), so that Morris's end
  levels become the MORRIS_TAIL_QUANTILE quantiles rather than u = 0 or 1 (about +-7 sd).
  The physical value is ``Factor.ppf(u)`` either way.

Morris mu/mu_star are therefore per unit step in u or z, not in the factor's own unit.
Spacing cv, offset sigma0 and correlation length are not factors: they are parameters of
the random fields' distributions, not per-realisation inputs.
"""

from __future__ import annotations

from scipy.special import ndtr
from scipy.stats import qmc

from ..errors import ParameterError
from ..stochastic import check_base_samples, check_method, normal, uniform
from .indices import SampleMatrix
from .problem import make_problem
from .sample import UNBOUNDED, sample

#: Morris trajectories of a screening run (``--method morris``) of a study that is not a
#: Morris study: 20, the top of Campolongo et al.'s 10-20, at (groups + 1) drapes each.
MORRIS_SCREENING_TRAJECTORIES = 20


def study_problem(study) -> dict:
    """The SALib problem of a study in standard variables; its names are
    ``uqdrape.ensemble.sample_columns(study)``. Fields are groups of their KL modes."""
    factors = {name: normal(0.0, 1.0) if factor.salib_dist in UNBOUNDED else uniform(0.0, 1.0)
               for name, factor in study.uncertainty.factors.items()}
    fields = {name: spec.build_input(study.solver.rings, study.fabric.spacing_mm).kl(spec.kl_retained).n_variables
              for name, spec in study.uncertainty.fields.items()}
    try:
        return make_problem(factors, fields)
    except ValueError as err:
        raise ValueError(f"study {study.name!r} ({study.path}): {err}; add [uncertainty.*] inputs") from None


def sensitivity_base_samples(study, method: str) -> int:
    """Base samples (Sobol') or trajectories (Morris) of ``study`` run with ``method``."""
    method = check_method(method)
    base = study.sensitivity.base_samples
    if method == "morris" and study.sensitivity.method != "morris":
        return MORRIS_SCREENING_TRAJECTORIES
    if base is None:
        raise ValueError(f"method {method!r}: study {study.name!r} ({study.path}) has no [sensitivity] "
                         f"base_samples; set it (Sobol': a power of 2 >= 64)")
    return check_base_samples(method, base)


def sensitivity_sample(study, method: str | None = None) -> SampleMatrix:
    """The sample matrix of ``study`` with ``method`` (default: the study's own), seeded by the
    study seed. Rows are evaluations (drapes); see :class:`SampleMatrix`."""
    method = study.sensitivity.method if method is None else method
    if method == "none":
        raise ParameterError("method", f"study {study.name!r} has [sensitivity] method = \"none\"; give the "
                             "method sobol or morris")
    base = sensitivity_base_samples(study, method)
    problem = study_problem(study)
    if method == "sobol" and 2 * problem["num_vars"] > qmc.Sobol.MAXDIM:
        sizes = {name: problem["groups"].count(name) for name in study.uncertainty.fields}
        raise ValueError(
            f"study {study.name!r}: a Sobol' sample of {problem['num_vars']} variables needs a Sobol' sequence of "
            f"{2 * problem['num_vars']} dimensions, more than scipy's {qmc.Sobol.MAXDIM} (KL modes per field: "
            f"{sizes}); use fewer rings, a correlated field or a lower kl_retained")
    X, meta = sample(problem, method, base_samples=base, seed=study.seed)
    standard = X.copy()
    coded = [k for k in range(len(study.uncertainty.factors)) if problem["dists"][k] == "norm"]
    standard[:, coded] = ndtr(X[:, coded])
    return SampleMatrix(problem, X, standard, meta)
