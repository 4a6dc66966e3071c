"""Rare-event estimates against plain Monte Carlo on cases with bounded factors and maxima
over the net (issue 39). Run: python benchmarks/bench_rare_bounded.py [--case energy|lock|energy-normal|dome]
[--case analytic] [--mc 100000] [--repeats 10] [--p 1e-3] [--workers N]

For each case the threshold t is the (1 - p) quantile of ``--mc`` plain drapes (their P
estimate has CoV sqrt((1 - p) / (p mc)): 10 % at 1e-3 from 100,000), and ``--repeats``
runs of the ``[study] rare`` estimator (``uqdrape.workflow.rare.estimate``: the study's
own limit state, response surface in the factors' own values, target CoV ``--cov``
within ``--max-drapes``) are compared with it: their mean, the observed spread (CoV of
the estimates about the MC P, the MC P's own variance taken out), the stated CoV, the
drapes a run, budget hits and methods, and the plain MC drapes that the observed accuracy
would need, (1 - P) / (P CoV^2), over the estimator's drapes: the ratio the issue asks
>= 10 (energy) and >= 3 (lock).

- ``energy``: energy drapes of the nose cone at 126 N, 4 rings coarser than the thesis
  net (rings 12), friction U[0.15, 0.3] (bounded), orientation N(0, 2 deg), iid spacing cv
  2 %: P(blankholder_energy >= t).
- ``lock``: geodesic drapes of the 50 mm dome, 8 rings, iid spacing cv 2 % and a skew of sd
  3 deg: P(lock_margin >= t), the largest cell shear over its locking angle (a maximum over
  the net, locks at either skew sign).

- ``energy-normal``: the ``energy`` case with friction N(0.2, 0.02) (every factor normal).
- ``dome``: the headline case of ``bench_fewer_drapes.py`` (part ``drape``): geodesic drapes
  of the 50 mm dome, 6 rings, spacing cv 2 %, skew sd 1 deg: P(mean_shear_positive >= t),
  one most probable point.

- ``analytic``: 30 repeats on limit states of known P (``uqdrape.reliability``'s linear
  and bounded-factor ones, and two half-spaces), no drapes: the stated CoV against the
  observed spread, and the calls against plain MC's at that spread.

Plain drapes and the repeats run in parallel over ``--workers`` processes (default: all
cores), one numba thread each. A tiny run that only proves the script works:
``--mc 2000 --repeats 2 --p 1e-2 --max-drapes 3000``.
"""

from __future__ import annotations

import argparse
import functools
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from types import SimpleNamespace

import numpy as np

CASES = {
    "energy": ("blankholder_energy", """\
[study]
name = "rare-energy"
seed = 39
realizations = 8
[geometry]
kind = "nose_cone"
[fabric]
material = "ebxhd936_like"
spacing_mm = 5.0
[process]
blankholder_force_N = 126.0
[solver]
mode = "energy"
rings = 12
[uncertainty.friction]
dist = "uniform"
bounds = [0.15, 0.3]
[uncertainty.orientation]
dist = "normal"
mean = 0.0
sd = 2.0
[uncertainty.spacing]
cv = 0.02
"""),
    "lock": ("lock_margin", """\
[study]
name = "rare-lock"
seed = 39
realizations = 8
[geometry]
kind = "hemisphere"
radius = 50.0
[fabric]
material = "generic_woven"
spacing_mm = 5.0
[process]
blankholder_force_N = 50.0
[solver]
mode = "geodesic"
rings = 8
[uncertainty.spacing]
cv = 0.02
[uncertainty.skew]
dist = "normal"
mean = 0.0
sd = 3.0
"""),
}
CASES["energy-normal"] = ("blankholder_energy", CASES["energy"][1].replace("rare-energy", "rare-energy-normal").replace(
    'dist = "uniform"\nbounds = [0.15, 0.3]', 'dist = "normal"\nmean = 0.2\nsd = 0.02'))
CASES["dome"] = ("mean_shear_positive", CASES["lock"][1].replace("rare-lock", "rare-dome").replace(
    "rings = 8", "rings = 6").replace("sd = 3.0", "sd = 1.0"))
#: Plain drapes a batch (one call of the limit state in a worker).
BATCH = 1000


@functools.lru_cache
def _study(case: str):
    from uqdrape.study import load_study

    folder = Path(tempfile.mkdtemp(prefix="bench-rare-"))
    path = folder / f"{case}.toml"
    path.write_text(CASES[case][1] + f'[output]\ndirectory = "{folder / "out"}"\n', encoding="utf-8")
    return load_study(path)


def _plain(case: str, seed: int, n: int) -> np.ndarray:
    """The QoI of n plain drapes of ``case`` from standard normals of ``seed``."""
    from uqdrape.workflow.rare import drape_limit_state

    g, d = drape_limit_state(_study(case), CASES[case][0], 0.0)
    rng = np.random.default_rng([39, seed])
    return np.concatenate([-g(rng.standard_normal((min(BATCH, n - k), d))) for k in range(0, n, BATCH)])


def _estimate(case: str, threshold: float, cov: float, max_drapes: int, seed: int) -> dict:
    """One run of the [study] rare estimator of P(QoI >= threshold) with ``seed``."""
    from uqdrape.workflow.rare import estimate

    study = _study(case)
    spec = SimpleNamespace(qoi=CASES[case][0], threshold=threshold, cov=cov, max_drapes=max_drapes)
    start = time.perf_counter()
    entry = estimate(study, spec, seed, study.force_levels[0])[0]
    return {**entry, "seconds": time.perf_counter() - start}


def run_case(case: str, args, pool) -> None:
    qoi = CASES[case][0]
    start = time.perf_counter()
    parts = [(case, k, len(c)) for k, c in enumerate(np.array_split(np.arange(args.mc), max(args.workers * 4, 1)))]
    value = np.concatenate(list(pool.map(_plain, *zip(*parts))))
    seconds = time.perf_counter() - start
    threshold = float(np.quantile(value, 1 - args.p))
    p_mc = float(np.mean(value >= threshold))
    cov_mc = np.sqrt((1 - p_mc) / (p_mc * args.mc))
    print(f"\n## {case}: P({qoi} >= t), {args.mc:,} plain drapes in {seconds:.0f} s on {args.workers} workers: "
          f"t = {threshold:.6g}, P = {p_mc:.4g} (CoV {cov_mc:.3f}) ({load()})")
    start = time.perf_counter()
    runs = list(pool.map(_estimate, *zip(*[(case, threshold, args.cov, args.max_drapes, s)
                                            for s in range(args.repeats)])))
    seconds = time.perf_counter() - start
    est = np.array([r["probability"] for r in runs])
    stated = np.array([r["cov"] for r in runs])
    drapes = np.array([r["drapes"] for r in runs])
    # the estimates' spread about MC's P, its own variance taken out (floored at the sample sd)
    about = np.sqrt(max(np.mean((est / p_mc - 1) ** 2) - cov_mc**2, 0.0))
    spread = max(about, est.std(ddof=1) / p_mc) if len(est) > 1 else about
    mc_equal = (1 - p_mc) / (p_mc * spread**2) if spread > 0 else np.inf
    methods = {m: int(sum(r["method"] == m for r in runs)) for m in sorted({r["method"] for r in runs})}
    notes = sorted({r["note"] for r in runs if r["note"]})
    print(f"estimator, {args.repeats} runs to CoV {args.cov} within {args.max_drapes:,} drapes ({seconds:.0f} s): "
          f"mean P {est.mean():.4g} ({est.mean() / p_mc:.3f} x MC's), observed CoV {spread:.3f}, stated "
          f"{stated.mean():.3f} (ratio {spread / stated.mean():.2f}); "
          f"{np.mean(np.abs(est / p_mc - 1) <= 2 * stated):.0%} within 2 stated CoV of MC's P; drapes a run "
          f"{drapes.mean():,.0f} (max {drapes.max():,}, budget hit "
          f"{int(np.sum(drapes >= args.max_drapes))}); methods {methods}; median beta "
          f"{np.nanmedian([r['beta'] if r['beta'] is not None else np.nan for r in runs]):.2f}")
    print(f"plain MC drapes at the observed CoV: {mc_equal:,.0f}; ratio to the estimator's "
          f"{mc_equal / drapes.mean():.1f}"
          + (f"; notes: {'; '.join(notes)}" if notes else "") + f" ({load()})")


#: Analytic limit states with known P, 30 repeats each (``--case analytic``): name -> (d, cov).
ANALYTIC = {"linear 100-d": (100, 0.1), "bounded factor, surface in its value": (50, 0.1),
            "bounded factor, surface in U": (50, 0.1), "two half-spaces 10-d": (10, 0.2)}


def _analytic(name: str, p: float, seed: int):
    """One estimate of analytic case ``name`` at P = p: (P, stated CoV, calls, method, exact P)."""
    from scipy import stats

    from uqdrape.reliability import bounded_limit_state, importance_sampling, linear_limit_state

    d, cov = ANALYTIC[name]
    features = None
    if name.startswith("linear"):
        g, exact = linear_limit_state(d, p)
    elif name.startswith("bounded"):
        g, exact, values = bounded_limit_state(d, p)
        features = values if "its value" in name else None
    else:
        beta, a = -stats.norm.ppf(p / 2), np.ones(d) / np.sqrt(d)

        def g(u):
            return beta - np.abs(np.asarray(u) @ a)

        exact = p
    r = importance_sampling(g, d, seed=seed, cov=cov, max_calls=20_000, features=features)
    return r.probability, r.cov, r.calls, r.method, exact


def analytic_part(args, pool, repeats: int = 30) -> None:
    print(f"\n## analytic limit states at P = {args.p:g}, {repeats} repeats each, budget 20,000 ({load()})")
    print("| case | target CoV | mean / exact | observed CoV | stated CoV | observed / stated | calls (max) | "
          "plain MC at the observed CoV | ratio | methods |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, (d, cov) in ANALYTIC.items():
        runs = list(pool.map(_analytic, *zip(*[(name, args.p, s) for s in range(repeats)])))
        est, stated, calls = (np.array([r[k] for r in runs]) for k in range(3))
        exact = runs[0][4]
        observed = est.std(ddof=1) / exact
        mc = (1 - exact) / (exact * observed**2)
        methods = {m: sum(r[3] == m for r in runs) for m in sorted({r[3] for r in runs})}
        print(f"| {name} | {cov} | {est.mean() / exact:.3f} | {observed:.3f} | {stated.mean():.3f} | "
              f"{observed / stated.mean():.2f} | {calls.mean():,.0f} ({calls.max():,.0f}) | {mc:,.0f} | "
              f"{mc / calls.mean():.1f} | {methods} |")


def load() -> str:
    return f"load average {os.getloadavg()[0]:.2f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=(*CASES, "analytic"), action="append")
    parser.add_argument("--mc", type=int, default=100_000, help="plain drapes of the reference (>= 100,000)")
    parser.add_argument("--repeats", type=int, default=10, help="estimator runs (>= 10)")
    parser.add_argument("--p", type=float, default=1e-3, help="P the threshold is set at")
    parser.add_argument("--cov", type=float, default=0.1, help="the estimator's target CoV")
    parser.add_argument("--max-drapes", type=int, default=20_000, help="the estimator's budget")
    parser.add_argument("--workers", type=int, default=os.cpu_count())
    args = parser.parse_args()
    os.environ["NUMBA_NUM_THREADS"] = "1"  # one thread a worker: the workers are the parallelism
    import multiprocessing

    with ProcessPoolExecutor(args.workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        for case in args.case or (*CASES, "analytic"):
            if case == "analytic":
                analytic_part(args, pool)
            else:
                run_case(case, args, pool)


if __name__ == "__main__":
    main()
