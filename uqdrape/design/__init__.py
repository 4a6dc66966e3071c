"""Blank-holder design under uncertainty: the force (total, or per sector) that keeps a
part inside its limits while the fabric and the process scatter.

A study's ``[design]`` section (``uqdrape.study.spec.Design``) names the decision
variables -- the total blank-holder force, or the forces of N equal angular sectors
(from +x, anticlockwise; the solver's ``sectors`` weights are the forces over their
sum), optionally the friction coefficient -- each with bounds, a total-force budget, and
an objective from :data:`~uqdrape.study.spec.DESIGN_OBJECTIVES`. The uncertain inputs
are the study's fields and factors. Plain-function flow (one module each)::

    problem(study) -> Evaluator (evaluate: batches of designs) -> optimise -> result_dataset

and ``uqdrape.workflow.run_design`` runs it in a study's output folder (its lock, its
worker pool, ``design.nc``).

Estimators (sample-average approximation with common random numbers). Every candidate
design drapes the same realisations 0..R-1 of the study (``sampled_inputs``: the same
seeds, fields and factors); only force, sectors and friction differ, so the objective is
a deterministic function of the design and two candidates differ by their effect, not
by sampling noise. A design's statistics, with ``confidence`` limits:

- ``p_locked``: P(any node of the net locked), Wilson score interval;
- ``q95_max_abs_shear``: the 95 % quantile of the largest |node shear| (deg),
  distribution-free order-statistic interval;
- ``abs_mean_asymmetry``: |mean asymmetry| (deg) of ``uqdrape.stats.line_means`` over
  line nodes 1..k_max, k_max fixed by the baseline design's realisations; Student-t
  interval of the mean, folded at 0;
- ``q95_max_draw_in``: the 95 % quantile of the largest :func:`draw_in` of the held edge
  (mm), order-statistic interval.

The design minimises the statistic's upper limit (``statistic = "upper"``, the default)
or its estimate, or with ``target`` the distance |value - target| (e.g. the force where
the upper limit of |mean asymmetry| falls to 1 deg).

Draw-in limit. With ``max_draw_in_mm`` a design is feasible when the same statistic
(upper limit or estimate) of ``q95_max_draw_in`` is at most the limit. Both optimisers
see an infeasible design's value as ``INFEASIBLE`` + its excess (mm), above every
feasible value, so they rank it after every feasible design and, among infeasible
ones, by how far they miss; the optimum is the best feasible design evaluated (the
least infeasible if none is). More force holds the edge, so the limit is a floor on the
force where the held edge would otherwise be pulled in too far.

Rare constraint. With ``rare`` (``[design] rare = {qoi, threshold, max_probability, cov,
max_drapes}``) a design is feasible also when the same statistic of its P(qoi >=
threshold) is at most ``max_probability``: the upper limit is the log-normal one of the
estimate and its CoV (:func:`rare_interval`). An estimate whose CoV is above the
constraint's target is not to be trusted: its upper limit is 1 and the design is not
feasible, whatever its P (``estimators.rare_statistic``); certain failure is P = 1, and a
candidate whose drapes never reach the threshold has an upper bound as its P (method
"below", CoV 0). The estimate is the ``[study] rare`` one
(``uqdrape.workflow.rare.design_rare``, passed in as the Evaluator's ``rare``: this
package does not drape limit states itself), one per design and sample with the sample's
seed, kept in the design's record (``rare_*`` attributes) and in ``design.nc``. Its
excess adds log10(P / max_probability) (decades) to the draw-in's (mm): a ranking of
infeasible designs, not a quantity.

Optimisers (deterministic: scipy, fixed seed, a deterministic objective):

- one variable (the total force): a grid of ``GRID`` forces over the bounds (one
  parallel batch), then ``scipy.optimize.minimize_scalar(method="bounded")`` between the
  grid neighbours of the best grid force, ``xatol = tolerance_N``;
- several (sector forces, or force and friction): ``scipy.optimize.differential_evolution``
  (population ``DE_POPSIZE`` x variables, latin hypercube start holding the equal split of
  the budget, no polishing, seed = study seed, a whole generation draped as one batch)
  with the budget as a linear constraint on the sum of the sector forces (candidates
  over budget are not draped); generations until ``max_evaluations`` designs have been
  draped. Its tolerance is that of a few generations: the optimum is the best design
  evaluated, not a converged point (the synthetic test finds a 200 N optimum of four
  sectors to 40 N in 60 designs).

Validation. The optimum and the baseline (the study's own force) are re-draped on an
independent sample: ``validation_realizations`` realisations of the study with seed
``validation_seed(study)`` (``numpy.random.SeedSequence([seed, VALIDATION_STREAM])``), so
the reported risk is not optimistically biased by the selection. A sector design also
drapes the uniform force at the optimum's total on both samples; the margin uniform -
sector has a paired bootstrap interval (the same realisations under both designs).

Force interval. The interval of the optimum force(s) is the 2.5-97.5 % range of the best
evaluated design (by the same objective) when the realisations are resampled
(``BOOTSTRAP`` resamples): how much the choice among the evaluated designs depends on
the sample. It cannot be wider than the designs evaluated around the optimum.

Files (in the output folder): ``evaluations/<key>.nc``, one per draped design and sample
(per-realisation quantities and node lock counts), written whole then renamed and keyed
by the study, the sample and the design vector, so a killed run replays the optimiser
from them and drapes only what is missing; ``design.nc``, every evaluated design with
its statistics, the history and the result.
"""

from .estimators import (DRAW_IN, INFEASIBLE, RARE, STATISTICS, excess, objective_value, penalised, rare_interval,
                         statistics)
from .evaluate import EVALUATIONS, RECORD_VERSION, Evaluator, drape_design
from .optimise import DE_POPSIZE, GRID, Result, optimise
from .problem import VALIDATION_STREAM, Problem, problem, validation_seed
from .result import BOOTSTRAP, DESIGN_FILE, result_dataset, summary_text

__all__ = ["problem", "Problem", "validation_seed", "Evaluator", "drape_design", "statistics", "excess",
           "objective_value", "penalised", "optimise", "Result", "result_dataset", "summary_text", "DESIGN_FILE",
           "EVALUATIONS", "RECORD_VERSION", "GRID", "DE_POPSIZE", "BOOTSTRAP", "VALIDATION_STREAM", "DRAW_IN",
           "INFEASIBLE", "STATISTICS", "RARE", "rare_interval"]
