"""The optimisers of a design problem: a grid and bounded Brent for one force,
differential evolution for several variables (see ``uqdrape.design``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..stats import line_means
from .estimators import penalised
from .evaluate import Evaluator
from .problem import Problem

#: Forces of the first batch of a one-variable design, evenly over the bounds.
GRID = 5
#: Differential evolution population per variable.
DE_POPSIZE = 3


@dataclass
class Result:
    """A finished design: the optimum and the designs draped on the validation sample
    (the history is the evaluator's ``order``)."""

    prob: Problem
    k_max: int
    optimum: tuple
    message: str
    validation: dict  # role -> x, draped on the validation sample


def optimise(prob: Problem, evaluate: Evaluator) -> Result:
    """Run the optimiser of ``prob`` (see the module notes); deterministic for a given
    study, so a rerun over the cached records replays it exactly."""
    spec, study = prob.spec, prob.study
    # the asymmetry averages line nodes 1..k_max, those valid in every realisation of the baseline design
    k_max = evaluate.k_max = int(line_means(evaluate([prob.baseline])[0]["line_shear"]).attrs["k_max"])

    def values(X):
        # to 12 significant digits: numpy's sums can differ in the last bit with the memory
        # alignment of an array (a record just draped, or read back from its file), and the
        # optimiser's next design must not, or a resumed run would leave the cached path
        return np.array([float(f"{penalised(s, spec):.12g}") for s in evaluate.statistics(X)])

    if len(prob.names) == 1:
        lo, hi = prob.bounds[0]
        grid = np.linspace(lo, hi, GRID)
        f = values(grid[:, None])
        b = int(np.argmin(f))
        left, right = grid[max(b - 1, 0)], grid[min(b + 1, GRID - 1)]
        left_over = spec.max_evaluations - GRID - 1
        res = optimize.minimize_scalar(lambda F: values([[F]])[0], bounds=(left, right), method="bounded",
                                       options={"xatol": spec.tolerance_N, "maxiter": max(left_over, 1)})
        message = f"grid of {GRID} forces, then bounded Brent on [{left:.1f}, {right:.1f}] N: {res.message}"
    else:
        n = prob.n_forces
        constraints = ()
        if spec.budget_N is not None and n > 1:
            a = np.zeros((1, len(prob.names)))
            a[0, :n] = 1.0
            constraints = (optimize.LinearConstraint(a, -np.inf, spec.budget_N),)
        population = DE_POPSIZE * len(prob.names)
        total = min(spec.budget_N or np.inf, n * prob.bounds[0][1])
        x0 = prob.uniform(total, prob.baseline)

        def spent(intermediate_result):  # infeasible candidates are never draped: count the designs that were
            return sum(sample == "design" for sample, _, _ in evaluate.order) >= spec.max_evaluations

        res = optimize.differential_evolution(
            lambda X: values(np.asarray(X).T), prob.bounds, constraints=constraints, seed=study.seed,
            popsize=DE_POPSIZE, maxiter=spec.max_evaluations, init="latinhypercube", polish=False,
            vectorized=True, updating="deferred", x0=x0, tol=0.0, callback=spent)
        message = f"differential evolution, population {population}, {res.nit} generations: {res.message}"
    history = [x for sample, _, x in evaluate.order if sample == "design"]
    f = values(history)
    optimum = history[int(np.argmin(f))]
    roles = {"baseline": prob.baseline, "optimum": optimum}
    if prob.n_forces > 1:
        roles["uniform"] = tuple(prob.uniform(sum(optimum[: prob.n_forces]), optimum))
        evaluate([roles["uniform"]])
    evaluate(list(roles.values()), "validation")
    return Result(prob, k_max, tuple(optimum), message, roles)
