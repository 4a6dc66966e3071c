"""uqdrape.reliability: probabilities of rare events, P(g(U) <= 0) for a limit state g of
standard normal variables U in any dimension (a drape's random fields and factors map
from them, ``uqdrape.ensemble.inputs_from_rows``), with the estimate's coefficient of
variation and the number of model calls it took.

``subset_simulation`` (Au & Beck 2001: nested intermediate failure domains, each
populated by modified Metropolis chains from the previous one's samples);
``importance_sampling`` (to a target CoV within a hard budget: importance sampling
around the most probable point the subset levels give, subset simulation in independent rounds
where no most probable point carries the probability, plain Monte Carlo where failure is not
rare, an upper bound where none is reached); ``limit_states`` holds analytic cases with
known P (linear, the sphere's exterior, a bounded factor plus noise) that check them.
"""

from .importance import RareResult, importance_sampling
from .limit_states import bounded_limit_state, linear_limit_state, sphere_limit_state
from .subset import SubsetResult, subset_simulation

__all__ = ["RareResult", "SubsetResult", "bounded_limit_state", "importance_sampling", "linear_limit_state",
           "sphere_limit_state", "subset_simulation"]
