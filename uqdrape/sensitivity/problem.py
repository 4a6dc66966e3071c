"""SALib problem definitions: scalar factors and random-field groups.

A scalar factor is one SALib variable with a distribution; a random field enters as
the group of its Karhunen-Loeve standard-normal variables, so Sobol'/Morris rank the
field as a whole. Factor parameters are in the factor's physical unit (N, degree, mm,
or dimensionless), except ``lognorm`` whose parameters are those of ln(X).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from SALib.util import extract_group_names

# SALib 1.6 distribution codes and the order of their entries in the problem's "bounds"
# (SALib.util._nonuniform_scale_samples): unif [low, high]; norm [mean, sd];
# truncnorm [low, high, mean, sd]; lognorm [mean, sd] of ln(X).
DIST_PARAMS: dict[str, tuple[str, ...]] = {
    "unif": ("low", "high"),
    "norm": ("mean", "sd"),
    "truncnorm": ("low", "high", "mean", "sd"),
    "lognorm": ("mean_log", "sd_log"),
}


@dataclass(frozen=True)
class Factor:
    """One SALib variable.

    name: label (unique in a problem); dist: a key of ``DIST_PARAMS``; params: that
    distribution's named parameters; group: the SALib group it belongs to (None for a
    scalar factor, which then forms its own group if the problem has groups).
    """

    name: str
    dist: str
    params: Mapping[str, float]
    group: str | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"Factor name must be a non-empty string, got {self.name!r}")
        if self.dist not in DIST_PARAMS:
            raise ValueError(
                f"Factor {self.name!r}: dist={self.dist!r} is not supported; "
                f"valid: {', '.join(DIST_PARAMS)}"
            )
        expected = DIST_PARAMS[self.dist]
        if set(self.params) != set(expected):
            raise ValueError(
                f"Factor {self.name!r} ({self.dist}): params has keys {sorted(self.params)}, "
                f"expected exactly {list(expected)}"
            )
        values = {}
        for key in expected:
            value = self.params[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(
                    f"Factor {self.name!r}: params[{key!r}]={value!r} must be a finite number"
                )
            values[key] = float(value)
        for key in ("sd", "sd_log"):
            if key in values and values[key] <= 0:
                raise ValueError(f"Factor {self.name!r}: params[{key!r}]={values[key]} must be > 0")
        if "low" in values and not values["low"] < values["high"]:
            raise ValueError(
                f"Factor {self.name!r}: params low={values['low']} must be < high={values['high']}"
            )
        if self.group is not None and (not isinstance(self.group, str) or not self.group):
            raise ValueError(f"Factor {self.name!r}: group must be a non-empty string or None, got {self.group!r}")
        object.__setattr__(self, "params", values)

    @property
    def bounds(self) -> list[float]:
        """The SALib "bounds" entry (parameters in SALib's order)."""
        return [self.params[key] for key in DIST_PARAMS[self.dist]]


def field_group(name: str, n_modes: int) -> list[Factor]:
    """The ``n_modes`` Karhunen-Loeve variables of random field ``name``.

    Variables are ``name[0] .. name[n_modes-1]``, standard normal (SALib "norm" with
    bounds [mean 0, sd 1]), all in group ``name``.
    """
    if isinstance(n_modes, bool) or not isinstance(n_modes, int) or n_modes < 1:
        raise ValueError(f"field {name!r}: n_modes={n_modes!r} must be an integer >= 1")
    return [
        Factor(f"{name}[{k}]", "norm", {"mean": 0.0, "sd": 1.0}, group=name)
        for k in range(n_modes)
    ]


def make_problem(factors: Sequence[Factor], fields: Mapping[str, int] | None = None) -> dict:
    """SALib problem dict from scalar factors and random fields {name: n_modes}.

    Keys: num_vars, names, bounds, dists, and groups when any factor is grouped (then
    every scalar factor is its own group, as SALib needs groups for all or none).
    Field variables follow the scalar factors. At least two factors/groups are needed.
    """
    everything = list(factors)
    for factor in everything:
        if not isinstance(factor, Factor):
            raise ValueError(f"factors must be Factor instances, got {factor!r}")
    for field_name, n_modes in (fields or {}).items():
        everything += field_group(field_name, n_modes)

    names = [f.name for f in everything]
    duplicated = sorted({n for n in names if names.count(n) > 1})
    if duplicated:
        raise ValueError(f"factor names must be unique; repeated: {duplicated}")

    grouped = any(f.group is not None for f in everything)
    groups = [f.group if f.group is not None else f.name for f in everything]
    scalar_names = {f.name for f in everything if f.group is None}
    group_names = {f.group for f in everything if f.group is not None}
    clash = sorted(scalar_names & group_names)
    if clash:
        raise ValueError(f"scalar factor names also used as group (field) names: {clash}")

    problem = {
        "num_vars": len(everything),
        "names": names,
        "bounds": [f.bounds for f in everything],
        "dists": [f.dist for f in everything],
    }
    if grouped:
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
        if dist not in DIST_PARAMS:
            raise ValueError(f"problem dist {dist!r} is not supported; valid: {', '.join(DIST_PARAMS)}")
    labels, n_groups = extract_group_names(problem)
    if n_groups < 2:
        raise ValueError(
            f"a sensitivity problem needs at least 2 factors or groups, got {n_groups} ({labels})"
        )
    return [str(label) for label in labels]
