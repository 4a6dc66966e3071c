"""Fabric architecture speed (issue 9): deriving a card, and mapping per-cell pre-strains.

Prints (1) the median time to derive the FGE 106hd card from its architecture file --
read, calibrate (pre-strain and compaction beta), sum the four energy terms on the
0.05 deg grid, differentiate and build the card -- as `uqdrape materials derive` does
(no plot, no file written), with a cold crossover path-line cache as in a fresh
process; (2) the median time to map 10^6 per-cell stitch pre-strains
to zero-force angles gamma0 with the precomputed table, and the one-off cost of that
table. Run: python benchmarks/bench_architecture.py [repeats]
"""

import statistics
import sys
import time

import numpy as np

from uqdrape.material.architecture import derive_card, load_architecture, zero_force_table
from uqdrape.material.architecture.crossover import crossover_slip


def median_time(fn, repeats):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def cold(fn):
    """fn without the crossover path-line cache, as in a fresh process."""
    def run():
        crossover_slip.cache_clear()
        return fn()
    return run


def main(repeats=7):
    derive = median_time(cold(lambda: derive_card(load_architecture("fge106hd"))), repeats)
    arch = load_architecture("fge106hd")
    table_cost = median_time(cold(lambda: zero_force_table(arch)), repeats)
    table = zero_force_table(arch)
    cells = np.random.default_rng(1).normal(arch.prestrain, 0.001, 10**6)
    mapping = median_time(lambda: table(cells), repeats)
    print(f"derive the fge106hd card (read + calibrate + sum + card), median of {repeats}: {derive:.3f} s")
    print(f"pre-strain -> gamma0 table (31 pre-strains, once per material), median of {repeats}: {table_cost:.3f} s")
    print(f"map 10^6 per-cell pre-strains to gamma0, median of {repeats}: {mapping:.3f} s")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
