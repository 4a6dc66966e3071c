"""SALib problem definitions: scalar factors and random-field groups.

Scalar factors are ``uqdrape.stochastic`` factors (their ``salib()`` gives SALib 1.6's
"dists" code and "bounds": unif [lower, upper]; norm [mean, sd]; truncnorm [lower,
upper, mean, sd]; lognorm [mean, sd] of ln X), in the factor's physical unit. A random
field enters as the group of its Karhunen-Loeve standard-normal variables, so
Sobol'/Morris rank the field as a whole.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping

from SALib.util import extract_group_names

from ..stochastic import Factor

_SALIB_DISTS = ("unif", "norm", "truncnorm", "lognorm")


def field_group(name: str, n_modes: int) -> list[str]:
    """Variable names ``name[0] .. name[n_modes-1]`` of random field ``name``'s KL modes."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"field name must be a non-empty string, got {name!r}")
    if isinstance(n_modes, bool) or not isinstance(n_modes, int) or n_modes < 1:
        raise ValueError(f"field {name!r}: n_modes={n_modes!r} must be an integer >= 1")
    return [f"{name}[{k}]" for k in range(n_modes)]


def make_problem(factors: Mapping[str, Factor], fields: Mapping[str, int] | None = None) -> dict:
    """SALib problem dict from scalar factors {name: Factor} and fields {name: n_modes}.

    Keys: num_vars, names, bounds, dists, and groups when there are fields: each field's
    KL variables (standard normal: "norm", bounds [0, 1]) form group ``name`` and every
    scalar factor is its own group (SALib needs groups for all variables or none).
    Field variables follow the scalar factors. Constant factors are not random and are
    left out. At least two factors/groups are needed.
    """
    names, bounds, dists = [], [], []
    for name, factor in factors.items():
        if not isinstance(name, str) or not name:
            raise ValueError(f"factor names must be non-empty strings, got {name!r}")
        if not isinstance(factor, Factor):
            raise ValueError(f"factor {name!r} must be a uqdrape.stochastic Factor, got {factor!r}")
        if factor.is_random:
            entry = factor.salib()
            names.append(name)
            bounds.append(list(entry["bounds"]))
            dists.append(entry["dists"])
    groups = list(names)
    for field_name, n_modes in (fields or {}).items():
        if field_name in factors:
            raise ValueError(f"{field_name!r} is both a scalar factor and a field name")
        variables = field_group(field_name, n_modes)
        clash = sorted(set(variables) & set(factors))
        if clash:
            raise ValueError(f"scalar factor names {clash} clash with field {field_name!r}'s variables")
        names += variables
        bounds += [[0.0, 1.0]] * n_modes
        dists += ["norm"] * n_modes
        groups += [field_name] * n_modes

    problem = {"num_vars": len(names), "names": names, "bounds": bounds, "dists": dists}
    if fields:
        problem["groups"] = groups
    check_problem(problem)
    return problem


def check_problem(problem: Mapping) -> list[str]:
    """Validate a SALib problem dict (ours or hand-written); return its group labels.

    The labels are SALib's: group names in order of first appearance, or the variable
    names when the problem has no groups.
    """
    for key in ("num_vars", "names", "bounds"):
        if key not in problem:
            raise ValueError(f"problem is missing key {key!r}; needs num_vars, names, bounds")
    n = problem["num_vars"]
    for key in ("names", "bounds", "dists", "groups"):
        if problem.get(key) is not None and len(problem[key]) != n:
            raise ValueError(f"problem[{key!r}] has {len(problem[key])} entries, num_vars is {n}")
    for dist in problem.get("dists") or []:
        if dist not in _SALIB_DISTS:
            raise ValueError(f"problem dist {dist!r} is not supported; valid: {', '.join(_SALIB_DISTS)}")
    names = list(problem["names"])
    repeated = sorted(name for name, count in Counter(names).items() if count > 1)
    if repeated:
        raise ValueError(f"problem names must be unique; repeated: {repeated}")
    labels, n_groups = extract_group_names(problem)
    if n_groups < 2:
        raise ValueError(
            f"a sensitivity problem needs at least 2 random factors or groups, got {n_groups} ({labels})"
        )
    return [str(label) for label in labels]
