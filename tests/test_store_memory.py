"""Statistics of a zarr store much larger than a chunk keep memory bounded (issue 28).

A 4,000-realisation geodesic ensemble of an 11 x 11 net (28 MB, 40 regions of 100
realisations, 0.7 MB each) is written to a file:// store. Its per-node statistics are
computed lazily from the store under tracemalloc (numpy's and zarr's buffers are
traced), with dask's block size set to 512 KiB so that the ensemble is many blocks:
the peak must not grow with the ensemble: from its first 1,000 realisations to all
4,000 it may rise by less than a quarter and by less than a third of the node shear the
three extra thousand add (0.97 MB), which a single rechunk of the variable to whole
columns held at once fails (8.15 MB at 4,000 against 5.21 MB at 1,000 with the same
settings: +2.94 MB; blocks of nodes each read with every realisation: 3.25 and 3.04 MB;
the order statistics narrowed by histograms, ``stats.summary.order_statistics``: 3.26 to
3.66 MB here, 3.86 to 3.90 MB in CI). The peak is not compared with the whole shear
(3.87 MB): about 3.3-3.9 MB of it is the same at any size (dask's graph, zarr's
metadata, the statistics' own arrays), so that margin was noise (CI measured 3.90 MB
once). The numbers equal those of the ensemble in memory.
``uqdrape export --to netcdf`` of the store streams it: its peak stays below a quarter
of the ensemble (4.7 MB measured).
"""

from __future__ import annotations

import tracemalloc

import dask
import pytest
import xarray as xr

from uqdrape.ensemble import open_ensemble, run_ensemble
from uqdrape.stats import node_statistics
from uqdrape.study import load_study
from uqdrape.workflow import export_result

from conftest import write_study

REALIZATIONS, CHUNK = 4000, 100


def peak_bytes(func):
    """(result, peak traced bytes) of ``func()``."""
    tracemalloc.start()
    try:
        return func(), tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.slow  # 4,000 drapes on 2 workers: ~20 s on the loaded 2-core machine, the statistics ~10 s
def test_store_statistics_memory_does_not_grow_with_the_ensemble(tmp_path):
    study = load_study(write_study(
        tmp_path, "big", study={"seed": 3, "realizations": REALIZATIONS, "chunk_size": CHUNK},
        solver={"mode": "geodesic", "rings": 5},
        uncertainty={"orientation": {"dist": "normal", "mean": 0.0, "sd": 2.0}}))
    url = f"file://{tmp_path}/store"
    run_ensemble(study, output_dir=url, workers=2, progress=False)
    full = open_ensemble(url)
    shear_bytes = full["shear"].nbytes
    assert len(full["shear"].chunks[1]) == REALIZATIONS // CHUNK and shear_bytes == REALIZATIONS * 121 * 8
    peaks = {}
    with dask.config.set({"array.chunk-size": "512KiB"}):
        for n in (REALIZATIONS // 4, REALIZATIONS):
            stats, peaks[n] = peak_bytes(lambda: node_statistics(open_ensemble(url).isel(realization=slice(0, n))))
    print(f"peak traced memory: {peaks[1000] / 1e6:.2f} MB for 1,000 realisations, {peaks[4000] / 1e6:.2f} MB for "
          f"4,000 (ensemble {full.nbytes / 1e6:.1f} MB, its shear {shear_bytes / 1e6:.2f} MB)")
    growth = peaks[REALIZATIONS] - peaks[REALIZATIONS // 4]
    assert growth < 0.25 * peaks[REALIZATIONS // 4]
    assert growth < (shear_bytes - shear_bytes // 4) / 3  # a whole column in memory would add all of it
    _, peaks["netcdf"] = peak_bytes(lambda: export_result(url, ["netcdf"], out=tmp_path / "all.nc"))
    print(f"peak traced memory of export --to netcdf: {peaks['netcdf'] / 1e6:.2f} MB")
    assert peaks["netcdf"] < full.nbytes / 4  # streamed: a few chunks of every variable, not the ensemble
    in_memory = node_statistics(full.load())
    quantiles = ["quantile_value", "quantile_lower", "quantile_upper"]  # sorted per node: the same numbers
    xr.testing.assert_identical(stats[quantiles], in_memory[quantiles])
    xr.testing.assert_allclose(stats.drop_vars(quantiles), in_memory.drop_vars(quantiles), rtol=1e-12)  # sum order
