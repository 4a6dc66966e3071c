"""Answers in fewer drapes (issue 29). Run: python benchmarks/bench_fewer_drapes.py [--part rqmc|subset|importance|drape|mlmc]

(a) ``rqmc``: randomised QMC against plain Monte Carlo on shipped studies, in one run:
    the Fig 5.19 study (``studies/nosecone-zero-angle.toml``, iid zero-angle field, 3600
    KL modes) and the blank-holder sweep (``studies/nosecone-blankholder-sweep.toml``,
    iid spacing field, 4 forces). Each is draped as N = K x M realisations twice: plain
    MC (``monte_carlo``) and ``rqmc`` with K randomisations of M points, same seed. Per
    QoI and force level: the variance of a mean over M drapes by MC (sd^2 / M, sd from the
    MC sample) and by one RQMC randomisation (the variance of the K randomisation means),
    their ratio (the variance reduction, with a 90 % chi-square interval from K - 1 dof),
    and the drapes needed for a stated 95 % half-width on the mean line shear:
    MC (t^2 sd^2 / h^2) against RQMC (M x the randomisations the t interval needs).
(b) ``subset``: subset simulation (``uqdrape.reliability``) on the linear limit state in
    100 dimensions at P = 1e-3, 1e-4, 1e-5: mean P, the spread of P over repeated runs
    against the stated CoV, and the model calls against plain MC's (1 - P) / (P CoV^2)
    for the same CoV; at 1e-4 the samples per level that give a 10 % CoV (over the runs)
    and their calls against MC's 10^6.
(b') ``importance``: importance sampling around the most probable point the subset levels give
    (``uqdrape.reliability.importance_sampling``, target CoV 10 %) on the linear limit
    state in 100 dimensions at 1e-3, 1e-4, 1e-5 and the sphere's exterior in 200 at 1e-4:
    mean P, CoV over repeated runs against the stated one, the share of runs whose
    2-CoV interval covers P, the model calls against plain MC's 100 / P for 10 %, and
    which estimate each run returned.
(c) ``drape``: a drape exceedance at P ~ 1e-3, cross-checked against plain MC: geodesic
    drapes of a 50 mm dome (6 rings, iid spacing cv 2 %, skew sd 1 deg: 313 standard
    variables), P(max |shear| >= t) (failing at either sign of the skew: two most probable
    points) and P(mean_shear_positive >= t) (one), t the 0.999 quantile of 200,000 MC
    drapes (MC's CoV 7 %), against 10 subset simulations of 1000 samples a level and 10
    importance samplings to 10 % CoV (``uqdrape.workflow.rare.drape_limit_state``).
(d) ``mlmc``: is a two-level Monte Carlo over net resolution worth it? Energy drapes of
    the nose cone with three scalar factors (friction, crossover offset, misalignment:
    the same values at both resolutions, so the levels couple exactly) on the thesis net
    (5 mm, 30 rings) and a coarse one (10 mm, 15 rings, the same extent): per QoI the
    variance of the fine value and of the fine - coarse difference, each level's CPU time
    a drape, and the two-level cost for the fine MC's variance, (sqrt(V_c C_c) +
    sqrt(V_d (C_f + C_c)))^2, against V_f C_f (Giles 2008).

The machine is shared: the load average (1 min) is printed before and after each part.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import stats

from uqdrape.ensemble import open_ensemble
from uqdrape.stats import SENSITIVITY_QOIS, realization_qois
from uqdrape.study import load_study
from uqdrape.study.spec import Sampling
from uqdrape.workflow import run_study

ROOT = Path(__file__).resolve().parent.parent
#: name: (K randomisations, M points, the stated 95 % half-width of the mean line shear in
#: deg: about a tenth of the line shear's sd in each study)
STUDIES = {"nosecone-zero-angle": (16, 16, 0.05), "nosecone-blankholder-sweep": (8, 16, 0.005)}
LINE_QOIS = ("mean_shear_positive", "mean_shear_negative")


def load() -> str:
    return f"load average {os.getloadavg()[0]:.2f}"


def qoi_values(study, plan, K, M, folder):
    """{qoi: (levels, K M) values} of the study draped with ``plan`` as K M realisations."""
    sampling = Sampling("rqmc", K) if plan == "rqmc" else Sampling("monte_carlo")
    run = dataclasses.replace(study, realizations=K * M, sampling=sampling, output_dir=Path(folder) / plan)
    start = time.perf_counter()
    out = run_study(run, workers=2, progress=False)
    seconds = time.perf_counter() - start
    with open_ensemble(out) as ds:
        qois = realization_qois(ds, SENSITIVITY_QOIS)
        forces = ds["blankholder_force"].values
    return {q: qois[q].transpose("blankholder_force", "realization").values for q in SENSITIVITY_QOIS}, forces, seconds


def rqmc_part() -> None:
    for name, (K, M, half_width) in STUDIES.items():
        study = load_study(ROOT / "studies" / f"{name}.toml")
        print(f"\n## {name}: K = {K} randomisations x M = {M} points = {K * M} drapes per plan and level ({load()})")
        with tempfile.TemporaryDirectory() as folder:
            mc, forces, t_mc = qoi_values(study, "monte_carlo", K, M, folder)
            qmc, _, t_qmc = qoi_values(study, "rqmc", K, M, folder)
        print(f"drapes: MC {t_mc:.0f} s, RQMC {t_qmc:.0f} s ({load()})")
        lo_chi, hi_chi = stats.chi2.ppf([0.95, 0.05], K - 1) / (K - 1)
        t_k = stats.t.ppf(0.975, K - 1)
        print("| QoI | F_BH (N) | MC var of an M-mean | RQMC var of an M-mean | reduction (90 % interval) |")
        print("|---|---|---|---|---|")
        for q in SENSITIVITY_QOIS:
            for level, force in enumerate(forces):
                var_mc = mc[q][level].var(ddof=1) / M
                var_rq = qmc[q][level].reshape(K, M).mean(axis=1).var(ddof=1)
                if var_mc == 0 and var_rq == 0:
                    print(f"| {q} | {force:g} | 0 | 0 | constant |")
                    continue
                ratio = var_mc / var_rq if var_rq > 0 else np.inf
                print(f"| {q} | {force:g} | {var_mc:.3g} | {var_rq:.3g} | {ratio:.1f} "
                      f"({ratio * lo_chi:.1f}-{ratio * hi_chi:.1f}) |")
        print(f"\ndrapes for a 95 % half-width of {half_width} deg on the mean line shear:")
        for q in LINE_QOIS:
            for level, force in enumerate(forces):
                sd = mc[q][level].std(ddof=1)
                n_mc = int(np.ceil((stats.norm.ppf(0.975) * sd / half_width) ** 2))
                sd_rep = qmc[q][level].reshape(K, M).mean(axis=1).std(ddof=1)
                k_needed = max(2, int(np.ceil((t_k * sd_rep / half_width) ** 2)))
                print(f"- {q} at {force:g} N: MC {n_mc}, RQMC {k_needed * M} ({k_needed} x {M}); "
                      f"ratio {n_mc / (k_needed * M):.1f}")


def subset_part() -> None:
    from uqdrape.reliability import linear_limit_state, subset_simulation

    d, repeats, n = 100, 100, 1000
    print(f"\n## subset simulation, linear limit state in d = {d}, {repeats} runs of {n} samples a level ({load()})")
    print("| P | mean estimate | CoV over runs | stated CoV (mean) | calls (mean) | MC calls, same CoV | ratio |")
    print("|---|---|---|---|---|---|---|")
    for p in (1e-3, 1e-4, 1e-5):
        g, exact = linear_limit_state(d, p)
        runs = [subset_simulation(g, d, n_per_level=n, seed=s) for s in range(repeats)]
        est = np.array([r.probability for r in runs])
        cov = np.array([r.cov for r in runs])
        calls = np.mean([r.calls for r in runs])
        observed = est.std(ddof=1) / exact
        mc = (1 - exact) / (exact * observed**2)
        print(f"| {exact:.0e} | {est.mean():.3g} | {observed:.3f} | {cov.mean():.3f} | {calls:.0f} | {mc:.3g} | "
              f"{mc / calls:.0f} |")
    g, exact = linear_limit_state(d, 1e-4)
    n10 = 12_000  # (0.335 / 0.1)^2 x 1000: the CoV of N = 1000 runs at 1e-4 (0.335) scaled as 1 / sqrt(N)
    runs = [subset_simulation(g, d, n_per_level=n10, seed=s) for s in range(repeats // 2)]
    est = np.array([r.probability for r in runs])
    calls = np.mean([r.calls for r in runs])
    observed = est.std(ddof=1) / exact
    print(f"\nP = 1e-4 with {n10} samples a level ({len(runs)} runs): CoV over runs {observed:.3f}, stated "
          f"{np.mean([r.cov for r in runs]):.3f}, calls {calls:.0f}; MC for that CoV "
          f"{(1 - exact) / (exact * observed**2):.3g}, for 10 %: {(1 - exact) / (exact * 0.01):.3g} ({load()})")


def importance_part() -> None:
    from uqdrape.reliability import importance_sampling, linear_limit_state, sphere_limit_state

    repeats = 100
    print(f"\n## importance sampling at the subset levels' most probable point, target CoV 0.1, {repeats} runs ({load()})")
    print("| limit state | d | P | mean estimate | CoV over runs | stated CoV (mean) | covered (2 CoV) | calls (mean) "
          "| MC calls for 10 % | ratio | estimate used |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for limit_state, d, p, runs in ((linear_limit_state, 100, 1e-3, repeats), (linear_limit_state, 100, 1e-4, repeats),
                                    (linear_limit_state, 100, 1e-5, repeats), (sphere_limit_state, 200, 1e-4, 20)):
        g, exact = limit_state(d, p)
        res = [importance_sampling(g, d, seed=s, cov=0.1) for s in range(runs)]
        est = np.array([r.probability for r in res])
        cov = np.array([r.cov for r in res])
        calls = np.mean([r.calls for r in res])
        mc = (1 - exact) / (exact * 0.01)
        used = {m: sum(r.method == m for r in res) for m in ("importance", "subset")}
        print(f"| {limit_state.__name__} | {d} | {exact:.0e} | {est.mean():.3g} | {est.std(ddof=1) / exact:.3f} | "
              f"{cov.mean():.3f} | {np.mean(np.abs(est / exact - 1) <= 2 * cov):.2f} | {calls:.0f} | {mc:.3g} | "
              f"{mc / calls:.0f} | {used} |")
    print(f"({load()})")


DOME_STUDY = """\
[study]
name = "rare-dome"
seed = 1
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
rings = 6
[uncertainty.spacing]
cv = 0.02
[uncertainty.skew]
dist = "normal"
mean = 0.0
sd = 1.0
"""


def drape_part() -> None:
    from uqdrape.reliability import importance_sampling, subset_simulation
    from uqdrape.workflow.rare import drape_limit_state

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "rare-dome.toml"
        path.write_text(DOME_STUDY)
        study = load_study(path)
    n_mc = 200_000
    for qoi in ("max_abs_shear", "mean_shear_positive"):
        print(f"\n## P({qoi} >= t) at P ~ 1e-3: {n_mc} MC drapes against subset simulation and importance "
              f"sampling ({load()})")
        g, d = drape_limit_state(study, qoi, 0.0)
        rng = np.random.default_rng(11)
        start = time.perf_counter()
        value = -np.concatenate([g(rng.standard_normal((2000, d))) for _ in range(n_mc // 2000)])
        seconds = time.perf_counter() - start
        threshold = float(np.quantile(value, 0.999))
        p_mc = float(np.mean(value >= threshold))
        print(f"MC: {n_mc} drapes in {seconds:.0f} s; t = {threshold:.4f} deg; P = {p_mc:.3g}, CoV "
              f"{np.sqrt((1 - p_mc) / (p_mc * n_mc)):.3f}")
        g, d = drape_limit_state(study, qoi, threshold)
        start = time.perf_counter()
        runs = [subset_simulation(g, d, n_per_level=1000, seed=s) for s in range(10)]
        seconds = time.perf_counter() - start
        est = np.array([r.probability for r in runs])
        print(f"subset simulation, 10 runs: mean P {est.mean():.3g} (spread CoV {est.std(ddof=1) / est.mean():.3f}, "
              f"stated {np.mean([r.cov for r in runs]):.3f}), {np.mean([r.calls for r in runs]):.0f} drapes a run, "
              f"{seconds / len(runs):.1f} s a run; MC drapes for the same CoV: "
              f"{(1 - p_mc) / (p_mc * (est.std(ddof=1) / est.mean()) ** 2):.3g} ({load()})")
        start = time.perf_counter()
        res = [importance_sampling(g, d, seed=s, cov=0.1) for s in range(10)]
        seconds = time.perf_counter() - start
        est = np.array([r.probability for r in res])
        calls = np.mean([r.calls for r in res])
        print(f"importance sampling to 10 % CoV, 10 runs: mean P {est.mean():.3g} (spread CoV "
              f"{est.std(ddof=1) / est.mean():.3f}, stated {np.mean([r.cov for r in res]):.3f}, "
              f"{np.mean(np.abs(est / p_mc - 1) <= 2 * np.array([r.cov for r in res])):.1f} within 2 stated CoV of MC's), "
              f"{calls:.0f} drapes a run ({np.mean([r.importance_calls for r in res]):.0f} importance), "
              f"{seconds / len(res):.1f} s a run, beta {np.mean([r.beta for r in res]):.2f}, fit R^2 "
              f"{np.mean([r.r2 for r in res]):.3f}, far-side share {np.mean([r.opposite for r in res]):.3f}, "
              f"estimates used {sorted({r.method for r in res})}; MC drapes for 10 %: "
              f"{(1 - p_mc) / (p_mc * 0.01):.3g}, ratio {(1 - p_mc) / (p_mc * 0.01) / calls:.0f} ({load()})")


NOSECONE_FACTORS = """\
[study]
name = "mlmc-nosecone"
seed = 29
realizations = {n}
chunk_size = {n}
[geometry]
kind = "nose_cone"
[fabric]
material = "ebxhd936_like"
spacing_mm = {spacing}
[process]
blankholder_force_N = 126.0
[solver]
mode = "energy"
rings = {rings}
[uncertainty.friction]
dist = "uniform"
bounds = [0.15, 0.3]
[uncertainty.crossover_x]
dist = "uniform"
bounds = [-3.0, 3.0]
[uncertainty.orientation]
dist = "normal"
mean = 0.0
sd = 2.0
"""


def mlmc_part(n: int = 64) -> None:
    from uqdrape.ensemble import drape_inputs, sampled_inputs

    print(f"\n## two-level MC over net resolution, {n} coupled drapes a level ({load()})")
    values, seconds = {}, {}
    with tempfile.TemporaryDirectory() as folder:
        for name, spacing, rings in (("fine", 5.0, 30), ("coarse", 10.0, 15)):
            path = Path(folder) / f"{name}.toml"
            path.write_text(NOSECONE_FACTORS.format(n=n, spacing=spacing, rings=rings))
            study = load_study(path)
            drape_inputs(study, [0], sampled_inputs(study, [0]))  # compile and warm up
            start = time.process_time()
            ds = drape_inputs(study, np.arange(n), sampled_inputs(study, np.arange(n)))
            seconds[name] = (time.process_time() - start) / n
            values[name] = ds
    fine_k = realization_qois(values["fine"], ["mean_shear_positive"]).attrs["k_max"]
    k = {"fine": fine_k - fine_k % 2, "coarse": (fine_k - fine_k % 2) // 2}  # the same line length, 5 k_fine mm
    print(f"CPU a drape: fine {1e3 * seconds['fine']:.0f} ms, coarse {1e3 * seconds['coarse']:.0f} ms; "
          f"line means over {5 * k['fine']:g} mm")
    print("| QoI | V fine | V (fine - coarse) | two-level cost / fine MC cost |")
    print("|---|---|---|---|")
    qois = {name: realization_qois(ds, SENSITIVITY_QOIS, k[name]) for name, ds in values.items()}
    for q in SENSITIVITY_QOIS:
        f, c = (qois[name][q].values.ravel() for name in ("fine", "coarse"))
        vf, vc, vd = f.var(ddof=1), c.var(ddof=1), (f - c).var(ddof=1)
        if vf == 0:
            print(f"| {q} | 0 | - | - |")
            continue
        cost = (np.sqrt(vc * seconds["coarse"]) + np.sqrt(vd * (seconds["fine"] + seconds["coarse"]))) ** 2
        print(f"| {q} | {vf:.3g} | {vd:.3g} | {cost / (vf * seconds['fine']):.2f} |")
    print(f"({load()})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("rqmc", "subset", "importance", "drape", "mlmc"), action="append")
    parts = parser.parse_args().part or ["rqmc", "subset", "importance", "drape", "mlmc"]
    if "rqmc" in parts:
        rqmc_part()
    if "subset" in parts:
        subset_part()
    if "importance" in parts:
        importance_part()
    if "drape" in parts:
        drape_part()
    if "mlmc" in parts:
        mlmc_part()


if __name__ == "__main__":
    main()
