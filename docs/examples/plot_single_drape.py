"""
A single drape of a hemisphere
==============================

One energy-minimising drape (thesis ch. 5) of the representative EBXhd-936-like
non-crimp fabric over a hemisphere of radius 100 mm, 12 rings of 5 mm cells, with a
blank-holder force of 100 N at friction 0.2. The result is an :class:`xarray.Dataset`
of node coordinates (mm) and node shear (degrees).
"""

import matplotlib.pyplot as plt

from uqdrape.drape import drape
from uqdrape.geometry import build
from uqdrape.material import load_material

ds = drape(build("hemisphere", radius=100.0), 5.0, 12, mode="energy",
           material=load_material("ebxhd936_like"), blankholder_force=100.0, friction=0.2)
net = ds.isel(realization=0)
print(f"largest |shear| {float(abs(net.shear).max()):.1f} deg")

# %%
# The net from above
# ------------------
# Each node coloured by its shear. The two quadrants that extend the stitch (positive
# shear, x y > 0) shear less than the two compliant ones.

fig, ax = plt.subplots(figsize=(6.4, 5.2))
dots = ax.scatter(net.x, net.y, c=net.shear, cmap="RdBu_r", vmin=-30, vmax=30, s=14)
fig.colorbar(dots, ax=ax, label="node shear (deg)")
ax.set(aspect="equal", xlabel="x (mm)", ylabel="y (mm)", title="hemisphere R 100 mm, 100 N")
plt.show()
