"""
A material card's shear curves
==============================

A material card gives the normalised shear force N_s(γ) (N/m) of a fabric's positive
and negative shear branches. Here the shipped representative card of the EBXhd-936
non-crimp fabric and the card derived from its fabric architecture (thesis ch. 4).
"""

import matplotlib.pyplot as plt
import numpy as np

from uqdrape.material import load_material

fig, ax = plt.subplots(figsize=(6.4, 4.2))
for name, colour in (("ebxhd936_like", "tab:red"), ("ebxhd936_derived", "tab:blue")):
    card = load_material(name)
    gamma_deg = np.linspace(-card.locking_angle_neg_deg, card.locking_angle_deg, 401)
    ax.plot(gamma_deg, card.shear_force(np.deg2rad(gamma_deg)), color=colour, label=name)
    print(f"{name}: locking +{card.locking_angle_deg:g} / -{card.locking_angle_neg_deg:g} deg")
ax.set(xlabel="shear angle γ (deg)", ylabel="$N_s$ (N/m)", yscale="symlog", title="shear curves")
ax.axhline(0.0, color="0.7", linewidth=0.8)
ax.legend()
plt.show()
