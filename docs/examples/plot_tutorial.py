"""
Tutorial: a study from Python
=============================

Load a study, run it, look at its ensemble as an xarray Dataset, map a confidence limit
per node, and rank the uncertain inputs by a sensitivity index. The study is small (a
hemisphere of radius 100 mm, 8 rings, 32 drapes at two blank-holder forces) so that it
runs in seconds; a shipped study (``studies/*.toml``) runs the same way. This page is
executed at every build of the documentation; download it as a notebook at its end.
"""

import tempfile
import textwrap
from pathlib import Path

import matplotlib.pyplot as plt

from uqdrape.ensemble import open_ensemble
from uqdrape.stats import exceedance_probability, node_statistics
from uqdrape.study import load_study
from uqdrape.workflow import open_sensitivity, run_study

folder = Path(tempfile.mkdtemp())
(folder / "tutorial.toml").write_text(textwrap.dedent(f"""
    [study]
    name = "tutorial"
    seed = 7
    realizations = 32

    [geometry]
    kind = "hemisphere"
    radius = 100.0

    [fabric]
    material = "ebxhd936_like"
    spacing_mm = 5.0

    [process]
    blankholder_force_N = [0.0, 200.0]   # a sweep: the same random numbers at both forces

    [solver]
    rings = 8

    [uncertainty.zero_angle]             # each cell's zero-energy shear angle, iid, sd 3 deg
    sd_deg = 3.0

    [uncertainty.friction]               # the blank-holder friction, uniform
    dist = "uniform"
    bounds = [0.1, 0.3]

    [output]
    directory = "{(folder / 'run').as_posix()}"
    """))

# %%
# Load and run
# ------------
# ``load_study`` validates the file (a wrong key or value is one line naming it);
# ``run_study`` drapes the realisations (here in this process) and returns the folder.

study = load_study(folder / "tutorial.toml")
run = run_study(study, scheduler="synchronous", progress=False)

# %%
# The ensemble as a Dataset
# -------------------------
# Lazy and chunked (dask): nothing is read until a statistic asks for it. Every variable
# has the dimensions (``blankholder_force``, ``realization``, ...): shear in degrees at
# the net's nodes (``i``, ``j``), coordinates in mm.

ensemble = open_ensemble(run)
print(ensemble["shear"])

# %%
# Statistics and a confidence map
# -------------------------------
# ``node_statistics`` reduces along ``realization``: per node the mean, sd and quantiles
# with their confidence limits; ``exceedance_probability`` the probability that a node
# shears past a threshold, with its Wilson interval. Here the upper 95 % limit of
# P(\|shear\| > 8°) at each node, at both forces: the force lowers it.

stats = node_statistics(ensemble)
print(f"largest node sd: {float(stats['sd'].max()):.2f} deg")
risk = exceedance_probability(ensemble, threshold_deg=8.0)
net = ensemble.isel(realization=0)
fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), layout="constrained")
for ax, force in zip(axes, risk.blankholder_force.values):
    level = net.sel(blankholder_force=force)
    dots = ax.scatter(level.x, level.y, c=risk["probability_upper"].sel(blankholder_force=force),
                      cmap="magma_r", vmin=0, vmax=1, s=30)
    ax.set(aspect="equal", xlabel="x (mm)", ylabel="y (mm)", title=f"{force:g} N")
fig.colorbar(dots, ax=axes, label="upper 95 % limit of P(|shear| > 8°)")
plt.show()

# %%
# A sensitivity index
# -------------------
# The same study with a Morris screening sample instead of the Monte Carlo sample
# (written beside the run, in ``run-morris``): which input moves the asymmetry of the
# max-shear lines, at each force? Without blank-holder force the friction does nothing.

screening = run_study(study, method="morris", scheduler="synchronous", progress=False)
indices, maps = open_sensitivity(screening)
print(indices["mu_star"].sel(qoi="asymmetry").to_pandas())
