"""Card slope and the scatter it gives an energy drape (issue 24): predicted and measured.

A card's specimen scatter ``[uncertainty.card]`` drapes each realisation on its own curve
N_s = mean + z sd. The energy solver's free variables are each ring's four generator-arm
turns t_k (the drape's ``turn``), not node angles: ring k's turns zero the gradient
G_k = dE_k/dt_k of its step energy, which depends on the turns of the rings before it
(they placed the nodes ring k is filled from) and on z. Linearised about the nominal drape,

    A dt = -q dz,   A = dG/dt (lower block-triangular: A_kk the stiffness of ring k's own
                    balance, K_s + K_bh + K_b; A_kj, j < k, how an earlier turn moves it),
                    q = dG/dz (the force of the card's sd curve on each turn),

so the turns scatter with sd |dt/dz| (z ~ Normal(0, 1)) and node shear with |J dt/dz|,
J = dgamma/dt. Everything is evaluated with the solver's own step energy
(``EnergyRings.step_energy``) on nets placed at given turns (``place_at``), by central
differences: no perturbed drape is solved.

The cards: ``ebxhd936_like`` scaled by c = 1, 1/2, 1/4 (its slope at every angle, so at the
operating angles, in those ratios), with the same specimen sd on all three, SIGMA of the
unscaled positive branch and none on the negative branch (an NCF's asymmetry: a scatter
proportional to the whole card would only scale the shear energy, which moves nothing
without a blank-holder). Without blank-holder force the step energy is c (E_s + z SIGMA/c E_sd)
plus the small bending term, so the scatter of the flatter cards is exactly 2 and 4 times
that of c = 1; the blank-holder's stiffness K_bh, the same for every card, pulls the ratios
towards 1 as the force grows. Hemisphere R 100 mm, 5 mm spacing, 10 rings, mu 0.2, slip model.

``python tools/card_slope.py`` runs each card's study (one study per card, its force levels,
the same seed, so the same scores z on every card) through the workflow, compares with the
prediction and writes ``results/gallery/card-slope/`` (card_slope.json, card_slope.png).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import stats

from uqdrape.drape import drape
from uqdrape.drape.energy import BlankHolder
from uqdrape.drape.net import EnergyRings, NetProblem
from uqdrape.drape.solver import cell_shear, node_mean
from uqdrape.ensemble import open_ensemble
from uqdrape.geometry import build
from uqdrape.files import toml_text
from uqdrape.material import load_material
from uqdrape.material.scatter import card_scatter, scattered
from uqdrape.workflow import load_study, run_study

OUT = Path("results") / "gallery" / "card-slope"
BASE = "ebxhd936_like"
#: Scale c of the base card's curves (both branches): slope ratios 1 : 1/2 : 1/4.
SCALES = (1.0, 0.5, 0.25)
#: Specimen sd as a fraction of the unscaled positive branch, on every card.
SIGMA = 0.03
FORCES = (0.0, 10.0, 30.0, 100.0, 300.0)
GEOMETRY = {"kind": "hemisphere", "radius": 100.0}
SPACING, RINGS, FRICTION, MODEL = 5.0, 10, 0.2, "slip"
#: Minimiser tolerance (deg): the turns' scatter is 1e-3 to 1e-1 deg.
TOLERANCE = 1e-6
#: Central-difference steps: turn (rad) and score z.
STEP_TURN, STEP_Z = 1e-4, 1.0


def label(scale: float) -> str:
    """A card scale as a name: 0.25 -> "x0p25"."""
    return f"x{scale:g}".replace(".", "p")


def write_card(folder: Path, scale: float) -> Path:
    """The base card scaled by ``scale`` with the shared sd, as a card TOML in ``folder``."""
    base = load_material(BASE)
    doc = {"name": f"{BASE}_{label(scale)}", "description": f"{BASE} with N_s scaled by {scale:g}",
           "locking_angle_deg": base.locking_angle_deg, "locking_angle_neg_deg": base.locking_angle_neg_deg,
           "shear": {}, "scatter": {}}
    for branch in ("positive", "negative"):
        angles, ns = base.curve(branch)
        doc["shear"][branch] = {"angle_deg": angles.tolist(), "ns": (scale * ns).tolist()}
        sd = SIGMA * ns if branch == "positive" else 0.0 * ns
        doc["scatter"][branch] = {"angle_deg": angles.tolist(), "ns_sd": sd.tolist(), "specimens": 5}
    path = folder / f"card_{label(scale)}.toml"
    path.write_text(toml_text(doc), encoding="utf-8")
    return path


def write_study(folder: Path, scale: float, realizations: int, forces=FORCES, seed: int = 24) -> Path:
    """A study that varies only the card: ``[uncertainty.card]`` on the scaled card."""
    card = write_card(folder, scale)
    doc = {"study": {"name": f"card-slope-{label(scale)}", "seed": seed, "realizations": realizations,
                     "chunk_size": realizations},
           "geometry": GEOMETRY,
           "fabric": {"material": card.name, "spacing_mm": SPACING},
           "process": {"blankholder_force_N": list(forces), "friction": FRICTION, "blankholder_model": MODEL},
           "solver": {"mode": "energy", "rings": RINGS, "tolerance_deg": TOLERANCE},
           "uncertainty": {"card": {"dist": "normal", "mean": 0.0, "sd": 1.0}},
           "output": {"directory": str(folder / f"run-{label(scale)}")}}
    path = folder / f"card-slope-{label(scale)}.toml"
    path.write_text(toml_text(doc), encoding="utf-8")
    return path


def measured(study_path: Path) -> dict:
    """Run the study through the workflow: its scores z (realization,) and per force level
    the searched turns (level, realization, ring 2..n, arm) and node shear (level,
    realization, i, j), deg."""
    out = run_study(study_path, scheduler="synchronous", progress=False)
    with open_ensemble(out) as ds:
        if not bool(ds["converged"].all()):
            raise RuntimeError(f"{study_path}: a drape did not converge")
        turn = ds["turn"].transpose("blankholder_force", "realization", "ring", "arm").values[:, :, 1:]
        shear = ds["shear"].transpose("blankholder_force", "realization", "i", "j").values
        return {"z": ds["card"].values, "turn": turn, "shear": shear}


def rms(sd) -> float:
    """Root mean square of the sds (deg) of the finite turns or nodes."""
    return float(np.sqrt(np.nanmean(np.asarray(sd, dtype=float) ** 2)))


def scatter(values) -> float:
    """``rms`` of the sd over realisations (axis 0) of turns (ring >= 2, arm) or node shear
    (i, j), deg."""
    return rms(np.asarray(values).std(0, ddof=1))


def ratio_se(flat, steep, seed: int = 0) -> float:
    """Bootstrap standard error of scatter(flat) / scatter(steep), realisations resampled
    in pairs: both studies drew the same scores z (same seed), so realisation r is the same
    specimen score on both cards."""
    index = np.arange(len(flat))
    stat = lambda r: scatter(flat[r.astype(int)]) / scatter(steep[r.astype(int)])  # noqa: E731
    return float(stats.bootstrap((index,), stat, vectorized=False, n_resamples=1000, method="percentile",
                                 random_state=seed).standard_error)


class Linearised:
    """The linear response of an energy drape's turns and node shear to the card score z,
    about the drape at z = 0 (module docstring). ``card`` is a study's card path."""

    def __init__(self, card, force: float):
        self.surface = build(GEOMETRY["kind"], radius=GEOMETRY["radius"])
        base, self.scatter = load_material(card), card_scatter(card)
        self.card = {z: scattered(base, self.scatter, z) for z in (-STEP_Z, 0.0, STEP_Z)}
        self.force, self.n = float(force), RINGS
        nominal = drape(self.surface, SPACING, RINGS, mode="energy", material=self.card[0.0],
                        blankholder_force=force, friction=FRICTION, blankholder_model=MODEL, tolerance=TOLERANCE)
        self.turn = np.deg2rad(nominal["turn"].values[0])  # (n, 4) rad

    def rings(self, materials, force: float) -> EnergyRings:
        """The solver's ring steps for a batch of realisations, one per material, with the
        studies' settings: orientation 0, the crossover at the apex, nominal segments."""
        R, n, s = len(materials), self.n, SPACING
        prob = NetProblem(
            self.surface, s, n, np.zeros((R, 2)), np.tile([0.0, np.pi / 2, np.pi, 1.5 * np.pi], (R, 1)),
            np.full((R, 2 * n, 2 * n + 1), s), np.full((R, 2 * n + 1, 2 * n), s), np.zeros((R, 2 * n, 2 * n)),
            np.tile([1.0, 0.0], (R, 1)), np.tile([0.0, 1.0], (R, 1)),
            BlankHolder(np.full(R, force), np.full(R, FRICTION), model=MODEL), list(materials),
            1e-11 * max(float(self.surface.size), 1.0))
        return EnergyRings(prob, materials[0].bending_stiffness, np.deg2rad(TOLERANCE), 30, np.deg2rad(10.0))

    def nets(self, steps: EnergyRings, turns: np.ndarray) -> np.ndarray:
        """Nets P (R, N, N, 3) placed ring by ring at ``turns`` (R, n, 4) rad."""
        P, status = steps.prob.start()
        for k in range(1, self.n + 1):
            steps.place_at(P, status, k, turns[:, k - 1])
        return P

    def gradients(self, steps: EnergyRings, P: np.ndarray, turns: np.ndarray) -> np.ndarray:
        """G (R, n - 1, 4): each ring k >= 2's step-energy gradient (J/rad) at ``turns``,
        from the rings < k of P."""
        R, h = turns.shape[0], STEP_TURN
        G = np.empty((R, self.n - 1, 4))
        idx = np.arange(-self.n, self.n + 1)
        ring_of = np.maximum(np.abs(idx)[:, None], np.abs(idx)[None, :])
        for k in range(2, self.n + 1):
            before = np.where((ring_of < k)[None, :, :, None], P, np.nan)
            for a in range(4):
                e = [steps.step_energy(before, k, turns[:, k - 1] + sign * h * np.eye(4)[a])[0] for sign in (1, -1)]
                G[:, k - 2, a] = (e[0] - e[1]) / (2 * h)
        return G

    def response(self) -> dict:
        """dt/dz of the searched turns (ring 2..n, arm) and dshear/dz (N, N), deg per unit z;
        the stiffness A and its shear (card and bending) part, J/rad^2, and q, J/rad per unit
        z, over the 4 (n - 1) searched turns."""
        m, h = 4 * (self.n - 1), STEP_TURN
        plus = np.tile(self.turn, (2 * m, 1, 1))
        for c in range(m):  # column c: turn (ring c // 4 + 2, arm c % 4) moved by +-h
            plus[2 * c, c // 4 + 1, c % 4] += h
            plus[2 * c + 1, c // 4 + 1, c % 4] -= h
        steps = self.rings([self.card[0.0]] * 2 * m, self.force)
        P = self.nets(steps, plus)
        columns = self.gradients(steps, P, plus)
        A = (columns[0::2] - columns[1::2]).reshape(m, m).T / (2 * h)
        unheld = self.rings([self.card[0.0]] * 2 * m, 0.0)
        columns = self.gradients(unheld, P, plus)
        A_shear = (columns[0::2] - columns[1::2]).reshape(m, m).T / (2 * h)
        gamma = np.rad2deg(node_mean(cell_shear(P)))
        J = (gamma[0::2] - gamma[1::2]).reshape(m, -1).T / (2 * h)  # deg per rad of turn
        cards = self.rings([self.card[-STEP_Z], self.card[STEP_Z]], self.force)
        nominal = np.tile(self.turn, (2, 1, 1))
        G = self.gradients(cards, self.nets(cards, nominal), nominal)
        q = (G[1] - G[0]).ravel() / (2 * STEP_Z)
        dt = -np.linalg.solve(A, q)
        return {"turn": np.rad2deg(dt).reshape(self.n - 1, 4), "shear": (J @ dt).reshape(gamma.shape[1:]),
                "A": A, "A_shear": A_shear, "q": q}


def mode_stiffness(A: np.ndarray, k: int) -> float:
    """Ring k's own stiffness (J/rad^2) in the hemisphere's turn pattern (+, -, +, -) of the
    four arms (its card and blank-holder keep the arms' 180 deg symmetry)."""
    v = np.array([1.0, -1.0, 1.0, -1.0]) / 2.0
    block = A[4 * (k - 2):4 * (k - 1), 4 * (k - 2):4 * (k - 1)]
    return float(v @ block @ v)


def compare(folder: Path, realizations: int, forces=FORCES, scales=SCALES) -> dict:
    """Predicted and measured scatter per card scale and force (``scatter``: turns, node
    shear; deg), the MC standard error of each measured sd (sd / sqrt(2 (N - 1)), normal),
    the ratio of each card's scatter to the first (steepest) card's, predicted and measured
    with its bootstrap standard error, and ring n's own stiffness split into its card,
    bending and blank-holder parts (J/rad^2)."""
    rows, runs = [], {}
    se = 1.0 / np.sqrt(2 * (realizations - 1))
    for scale in scales:
        study = write_study(folder, scale, realizations, forces)
        card = load_study(study).fabric.material
        runs[scale] = got = measured(study)
        if not np.array_equal(got["z"], runs[scales[0]]["z"]):
            raise RuntimeError(f"{study}: its scores z are not those of the first card's study")
        bend = 2 * load_material(card).bending_stiffness / (SPACING * 1e-3)
        for f, force in enumerate(forces):
            lin = Linearised(card, force).response()
            k_total, k_shear = mode_stiffness(lin["A"], RINGS), mode_stiffness(lin["A_shear"], RINGS)
            row = {"scale": scale, "force_N": force, "z_sd": float(np.std(got["z"], ddof=1)),
                   "K_card": k_shear - bend, "K_bending": bend, "K_blankholder": k_total - k_shear}
            for key in ("turn", "shear"):
                row[f"{key}_sd_predicted"] = rms(lin[key])  # |d/dz| is the sd for z ~ Normal(0, 1)
                row[f"{key}_sd_measured"] = scatter(got[key][f])
                row[f"{key}_sd_se"] = row[f"{key}_sd_measured"] * se
                steep = next((r for r in rows if r["scale"] == scales[0] and r["force_N"] == force), row)
                row[f"{key}_ratio_predicted"] = row[f"{key}_sd_predicted"] / steep[f"{key}_sd_predicted"]
                row[f"{key}_ratio_measured"] = row[f"{key}_sd_measured"] / steep[f"{key}_sd_measured"]
                row[f"{key}_ratio_se"] = ratio_se(got[key][f], runs[scales[0]][key][f]) if scale != scales[0] else 0.0
            rows.append(row)
    return {"realizations": realizations, "base": BASE, "sigma": SIGMA, "rows": rows}


def plot(result: dict, path: Path) -> Path:
    """Turn and node-shear scatter against the card's relative slope, one colour per force:
    the linearised prediction (lines) and the studies' measured sd with 2 MC standard errors
    (points); and each flatter card's scatter over the steepest card's against the force."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result["rows"]
    forces = sorted({r["force_N"] for r in rows})
    scales = sorted({r["scale"] for r in rows})
    colours = dict(zip(forces, plt.cm.viridis(np.linspace(0, 0.85, len(forces)))))
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8), constrained_layout=True)
    for ax, key, label in ((axes[0], "turn", "ring-turn sd, rms over rings 2-10 and arms (deg)"),
                           (axes[1], "shear", "node-shear sd, rms over nodes (deg)")):
        for force in forces:
            sel = sorted((r for r in rows if r["force_N"] == force), key=lambda r: r["scale"])
            x = [r["scale"] for r in sel]
            ax.plot(x, [r[f"{key}_sd_predicted"] for r in sel], "-", color=colours[force])
            ax.errorbar(x, [r[f"{key}_sd_measured"] for r in sel], yerr=[2 * r[f"{key}_sd_se"] for r in sel],
                        fmt="o", color=colours[force], capsize=3, label=f"{force:g} N")
        ax.set(xscale="log", yscale="log", ylabel=label, xlabel=f"card slope relative to {BASE} (N_s scaled)")
        ax.set_xticks(scales, [f"{s:g}" for s in scales])
        ax.set_xticks([], minor=True)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(title="blank-holder force; lines: linearised", fontsize=8, title_fontsize=8)
    ax = axes[2]
    steep = max(scales)
    flatter = sorted((s for s in scales if s != steep), reverse=True)
    for scale, colour in zip(flatter, ("tab:blue", "tab:red", "tab:orange")):
        for key, style in (("turn", "-"), ("shear", "--")):
            sel = sorted((r for r in rows if r["scale"] == scale), key=lambda r: r["force_N"])
            x = [r["force_N"] for r in sel]
            ax.plot(x, [r[f"{key}_ratio_predicted"] for r in sel], style, color=colour, lw=1)
            ax.errorbar(x, [r[f"{key}_ratio_measured"] for r in sel], yerr=[2 * r[f"{key}_ratio_se"] for r in sel],
                        fmt="o" if key == "turn" else "s", mfc="none" if key == "shear" else colour, color=colour,
                        capsize=3, label=f"slope {scale:g}: {'turns' if key == 'turn' else 'node shear'}")
        ax.axhline(steep / scale, color="0.7", lw=0.8, ls=":")
    ax.set_xscale("symlog", linthresh=10.0)
    ax.set_xlim(-1.0, 1.3 * max(forces))
    ax.set_xticks(forces, [f"{f:g}" for f in forces])
    ax.set(xlabel="blank-holder force (N)",
           ylabel=f"scatter over that of slope {steep:g} (same scores z)")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_ylim(0.9, 1.25 * steep / min(scales) + 0.3)
    ax.legend(fontsize=8, title="points: studies; lines: linearised; dotted: 1/slope", title_fontsize=8, ncol=2,
              loc="upper right")
    fig.suptitle(f"The same specimen sd ({result['sigma']:g} x {BASE}'s positive branch) on cards of different "
                 f"slope, {result['realizations']} drapes per card and force: hemisphere R 100 mm, 10 rings, mu 0.2. "
                 "Error bars: 2 MC standard errors", fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--realizations", type=int, default=64)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as folder:
        result = compare(Path(folder), args.realizations)
    (args.out / "card_slope.json").write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    plot(result, args.out / "card_slope.png")
    for r in result["rows"]:
        print(f"{label(r['scale']):6s} {r['force_N']:5g} N" + "".join(
            f"  {key} sd {r[f'{key}_sd_measured']:.5f} +- {r[f'{key}_sd_se']:.5f} (linearised "
            f"{r[f'{key}_sd_predicted']:.5f}), ratio {r[f'{key}_ratio_measured']:.3f} +- {r[f'{key}_ratio_se']:.3f} "
            f"({r[f'{key}_ratio_predicted']:.3f})" for key in ("turn", "shear"))
            + f"  K card / bending / blank-holder {r['K_card']:.3g} / {r['K_bending']:.3g} / {r['K_blankholder']:.3g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
