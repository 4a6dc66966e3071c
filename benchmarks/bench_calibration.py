"""Calibration speed (issue 25): the restricted-ML fit of a 40 x 40 grid (1,600 points)
of fibre angles, anisotropic (L1 = 20 mm, L2 = 10 mm on a 5 mm grid), with a nugget
(1 deg beside a field sd of 4 deg), drawn by the study's own field sampler.

Prints, per family and per way of evaluating the likelihood, the wall time of one
evaluation (value and gradient), of the ML fit (starting points + L-BFGS-B) and of the fit
with the profile-likelihood intervals of sd, L1 and L2, the evaluations each took, and the
load average. "grid": the points as measured, a tensor grid along the fibres, evaluated
through the 1-D eigenpairs; "dense": the same points moved by 1 µm along fibre 1 (no
longer a grid), so the full 1,600 x 1,600 covariance is factored and inverted at every
evaluation, as for scattered points. Then ``auto``: all three families fitted
and one kept (no intervals). BLAS threads are whatever OpenBLAS starts with: set
OPENBLAS_NUM_THREADS=1 or 2 to compare (on a loaded machine one thread is faster).
``--posterior``: also the emcee sample of ``uqdrape calibrate --posterior`` (its default
16 walkers x 1,500 steps) of each grid fit and of 38 scattered points (Table 5.1's size,
the exponential field of the same parameters), with its likelihood evaluations, acceptance
and autocorrelation times.

Run: python benchmarks/bench_calibration.py [--grid 40] [--no-intervals]
"""

import argparse
import os
import time

import numpy as np

from uqdrape.calibration import fit_field, synthetic_set
from uqdrape.calibration.likelihood import Likelihood
from uqdrape.calibration.posterior import posterior_sample

TRUTH = dict(sd_deg=4.0, length_mm=(20.0, 10.0), nugget_deg=1.0)


def _counted():
    """Count the likelihood evaluations (a wrapper on Likelihood.__call__)."""
    calls = [0]
    original = Likelihood.__call__

    def call(self, theta, gradient=True):
        calls[0] += 1
        return original(self, theta, gradient)

    Likelihood.__call__ = call
    return calls


def _time_posterior(label, fit, calls):
    """Time one default emcee posterior sample of ``fit`` and print what it cost."""
    calls[0] = 0
    post = posterior_sample(fit)
    tau = ", ".join(f"{k} {v:.0f}" for k, v in post.autocorrelation.items())
    print(f"  posterior ({label}): {post.seconds:.1f} s, {calls[0]} evaluations, acceptance "
          f"{post.acceptance:.2f}, autocorrelation (steps) {tau}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--grid", type=int, default=40, help="grid side (default 40: 1,600 points)")
    parser.add_argument("--no-intervals", action="store_true", help="time the fits only")
    parser.add_argument("--dense-intervals", action="store_true",
                        help="also time the dense way's intervals (minutes on a loaded machine)")
    parser.add_argument("--posterior", action="store_true", help="also time the emcee posterior sample")
    args = parser.parse_args()
    calls = _counted()
    print(f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, "
          f"load average {os.getloadavg()[0]:.1f}, {os.cpu_count()} cores")
    for family, way in [(f, w) for f in ("exponential", "squared_exponential") for w in ("grid", "dense")]:
        a, b, y = synthetic_set(np.random.default_rng(1), family, lattice=(args.grid, args.grid), **TRUTH)
        on_grid = a, b, y
        if way == "dense":
            a = a + 1e-3 * np.random.default_rng(2).random(len(a))  # up to 1 µm off the grid
        like = Likelihood(a, b, y, np.zeros(len(y)), family)
        assert (like.grid is None) == (way == "dense")
        theta = np.log([4.0, 20.0, 10.0, 1.0])
        like(theta)
        t0 = time.perf_counter()
        for _ in range(3):
            like(theta)
        per_eval = (time.perf_counter() - t0) / 3
        calls[0] = 0
        t0 = time.perf_counter()
        fit = fit_field(a, b, y, family=family, intervals=False)
        t_fit, n_fit = time.perf_counter() - t0, calls[0]
        c = fit.chosen
        print(f"{family}, {way}: {len(y)} points; one evaluation {per_eval:.3f} s; ML fit {t_fit:.1f} s "
              f"({n_fit} evaluations): sd {c.sd_deg:.3f}, L {c.length_mm[0]:.2f}, {c.length_mm[1]:.2f} mm, "
              f"nugget {c.nugget_deg:.3f} (truth 4, 20, 10, 1)")
        if not args.no_intervals and (way == "grid" or args.dense_intervals):
            calls[0] = 0
            t0 = time.perf_counter()
            fit = fit_field(a, b, y, family=family)
            t_all, n_all = time.perf_counter() - t0, calls[0]
            e = fit.estimates
            print(f"  with 90 % profile intervals {t_all:.1f} s ({n_all} evaluations): "
                  + ", ".join(f"{k} [{e[k].lower:.3g}, {e[k].upper:.3g}]"
                              for k in ("sd_deg", "length_1_mm", "length_2_mm")))
        if args.posterior and way == "grid":
            _time_posterior(f"{family}, grid", fit, calls)
    if args.posterior:
        a, b, y = synthetic_set(np.random.default_rng(3), "exponential", lattice=(12, 12), points=38, **TRUTH)
        _time_posterior("exponential, 38 scattered points", fit_field(a, b, y, family="exponential",
                                                                       intervals=False), calls)
    calls[0] = 0
    t0 = time.perf_counter()
    fit = fit_field(*on_grid, intervals=False)
    print(f"auto (3 families on the grid, no intervals): {time.perf_counter() - t0:.1f} s ({calls[0]} evaluations), "
          f"kept {fit.family}; load average now {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
