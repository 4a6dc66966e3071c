"""What the thesis's nose-cone trial says about the card: the mid-angle imbalance it implies (issue 38).

``python tools/card_imbalance.py`` writes ``results/gallery/card-imbalance/`` (README.md,
imbalance.json, imbalance.png):

1. **The thesis's statements as an interval.** Wiggers (2007, §5.2.4) formed EBXhd-936
   over the nose cone: asymmetric at 0 N, less at 126 N, "almost symmetric" at 252 N,
   "entirely symmetric" at 378 N. Read as "not yet symmetric at 252 N, symmetric at 378 N"
   (symmetric: the −/+ gap down to 10 % of its 0 N value, as ``uqdrape.symmetry``), it
   bounds the mid-angle imbalance ΔN(30°) of a card family
   (``uqdrape.material.imbalance``) by ``uqdrape.symmetry.imbalance_bounds``, for both
   blank-holder models and the thesis's two friction values (mu 0.2 in the text, 0.3 in
   Fig 5.6), in N_s = F_s/L (what a uqdrape card holds) and as F/L (if the thesis's
   plotted "normalised shear force" was the crosshead form: F/L = N_s · 2 cos(φ0 − θ/2),
   × √3 at 30°).
2. **A synthetic round trip.** Trials formed with a card of known ΔN(30°) (one part per
   force, its own zero-angle scatter, its gap read to ``READ_SD_DEG``) are turned back
   into ΔN by ``uqdrape.symmetry.gap_model(...).posterior``; the share of 95 % intervals
   that cover the truth is counted over ``--repeats`` trials.

The settings (mould, spacing, rings, orientation) are those of the gallery study
``nosecone-blankholder-levels-architecture``; the family is built on its card,
``ebxhd936_derived``. The picture-frame-scale card ``ebxhd936_like`` is tried too: its
family keeps that card's assumed end imbalance (850 against 83.5 N/m at 60°), and the
script reports the smallest 378 N gap ratio it reaches. A script of the checkout, like
tools/gallery.py.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = Path("results") / "gallery" / "card-imbalance"
STUDY = Path("studies") / "nosecone-blankholder-levels-architecture.toml"
#: The thesis's statements: not yet symmetric at 252 N, symmetric at 378 N.
ASYMMETRIC_AT, SYMMETRIC_AT = (252.0,), (378.0,)
MODELS, FRICTIONS = ("radial", "slip"), (0.2, 0.3)
#: The round trip: the true ΔN(30°) (N/m), the trial's forces (N), the parts' zero-angle
#: scatter (deg, iid per cell) and the sd (deg) to which a part's gap is read.
TRUTH_NM, TRIAL_FORCES, ZERO_ANGLE_SD_DEG, READ_SD_DEG = 5.0, (0.0, 126.0, 252.0, 378.0), 2.0, 0.5


def settings() -> dict:
    """Mould, spacing, rings and the drape keywords of :data:`STUDY` (friction and model apart)."""
    from uqdrape.study import load_study

    st = load_study(STUDY)
    f, s = st.fabric, st.solver
    return {"surface": st.geometry.build_mould(), "card": f.material, "spacing": f.spacing_mm, "rings": s.rings,
            "kwargs": {"orientation": f.orientation_deg, "crossover": tuple(f.crossover),
                       "tolerance": s.tolerance_deg, "max_iterations": s.max_iterations}}


def crosshead(value: float | None) -> float | None:
    """A ΔN(30°) in N_s = F_s/L (N/m) as F/L (N/m)."""
    from uqdrape.material.sheartest.picture_frame import shear_per_crosshead

    return None if value is None else value / float(shear_per_crosshead(np.deg2rad(30.0), np.deg2rad(45.0)))


def thesis_table(cfg: dict) -> list[dict]:
    """One row per blank-holder model and friction: the ΔN(30°) interval of the statements."""
    from uqdrape.material import load_material
    from uqdrape.symmetry import imbalance_bounds

    card = load_material(cfg["card"])
    rows = []
    for model in MODELS:
        for mu in FRICTIONS:
            t0 = time.perf_counter()
            b = imbalance_bounds(cfg["surface"], cfg["spacing"], cfg["rings"], card, asymmetric_at=ASYMMETRIC_AT,
                                 symmetric_at=SYMMETRIC_AT, friction=mu, blankholder_model=model, **cfg["kwargs"])
            rows.append({"model": model, "friction": mu, "lower_Fs_L": b.lower, "upper_Fs_L": b.upper,
                         "lower_F_L": crosshead(b.lower), "upper_F_L": crosshead(b.upper), "drapes": b.drapes,
                         "seconds": round(time.perf_counter() - t0, 1)})
            print(f"card_imbalance: {model:<6} mu {mu}: dN(30) in ({b.lower:.3g}, {b.upper:.3g}] N/m F_s/L "
                  f"({rows[-1]['seconds']} s)", file=sys.stderr)
    return rows


def ratio_curves(cfg: dict, values: np.ndarray) -> dict:
    """gap(F) / gap(0 N) at 252 and 378 N against ΔN(30°) (``values``), per model and friction."""
    from uqdrape.material import load_material
    from uqdrape.material.imbalance import with_imbalance
    from uqdrape.symmetry import quadrant_gaps

    card = load_material(cfg["card"])
    curves = {}
    for model in MODELS:
        for mu in FRICTIONS:
            kw = {**cfg["kwargs"], "friction": mu, "blankholder_model": model}
            k_max = quadrant_gaps(cfg["surface"], cfg["spacing"], cfg["rings"], card, [0.0], None, kw)[1]
            gaps = np.array([quadrant_gaps(cfg["surface"], cfg["spacing"], cfg["rings"], with_imbalance(card, v),
                                   [0.0, *ASYMMETRIC_AT, *SYMMETRIC_AT], k_max, kw)[0] for v in values])
            curves[f"{model}, mu {mu}"] = (gaps[:, 1:] / gaps[:, :1]).T.tolist()
    return curves


def like_family(cfg: dict) -> dict:
    """The PF-scale card's family (radial, mu 0.2): the 378 N gap ratio at its smallest ΔN(30°)."""
    from uqdrape.material import load_material
    from uqdrape.material.imbalance import imbalance, with_imbalance
    from uqdrape.symmetry import quadrant_gaps

    card = load_material("ebxhd936_like")
    kw = {**cfg["kwargs"], "friction": 0.2, "blankholder_model": "radial"}
    out = {"card": card.name, "own_dN30_Fs_L": imbalance(card)}
    for value in (0.5, 5.0):
        gaps = quadrant_gaps(cfg["surface"], cfg["spacing"], cfg["rings"], with_imbalance(card, value), [0.0, 378.0], None,
                     kw)[0]
        out[f"gap_ratio_378N_at_{value:g}"] = gaps[1] / gaps[0]
    return out


def round_trip(cfg: dict, repeats: int, seed: int = 38) -> dict:
    """Trials at :data:`TRUTH_NM` (radial, mu 0.2) calibrated back: coverage of the 95 % intervals."""
    from uqdrape.drape import drape
    from uqdrape.material import load_material
    from uqdrape.material.imbalance import with_imbalance
    from uqdrape.stats import line_scalars
    from uqdrape.symmetry import gap_model, quadrant_gaps

    card = load_material(cfg["card"])
    kw = {**cfg["kwargs"], "friction": 0.2, "blankholder_model": "radial"}
    surface, spacing, rings = cfg["surface"], cfg["spacing"], cfg["rings"]
    t0 = time.perf_counter()
    model = gap_model(surface, spacing, rings, card, TRIAL_FORCES, zero_angle_sd_deg=ZERO_ANGLE_SD_DEG,
                      realizations=16, grid=(1.0, 100.0), points=25, **kw)
    model_seconds = time.perf_counter() - t0
    rng = np.random.default_rng(seed)
    n, F = rings, len(TRIAL_FORCES)
    k_max = quadrant_gaps(surface, spacing, rings, card, [0.0], None, kw)[1]
    parts = drape(surface, spacing, rings, mode="energy", material=with_imbalance(card, TRUTH_NM),
                  blankholder_force=np.tile(TRIAL_FORCES, repeats),
                  gamma0=rng.normal(0.0, ZERO_ANGLE_SD_DEG, (repeats * F, 2 * n, 2 * n)), **kw)
    gaps = -line_scalars(parts, k_max)["asymmetry"].values.reshape(repeats, F)
    posts = [model.posterior(g + rng.normal(0.0, READ_SD_DEG, F), READ_SD_DEG) for g in gaps]
    covered = [p.interval[0] <= TRUTH_NM <= p.interval[1] for p in posts]
    example = posts[0]
    return {"truth_Fs_L": TRUTH_NM, "forces_N": list(TRIAL_FORCES), "zero_angle_sd_deg": ZERO_ANGLE_SD_DEG,
            "read_sd_deg": READ_SD_DEG, "repeats": repeats, "covered": int(sum(covered)),
            "coverage": float(np.mean(covered)),
            "median_interval": [float(np.median([p.interval[k] for p in posts])) for k in (0, 1)],
            "model_drapes": int(len(model.values) * F * model.realizations), "model_seconds": round(model_seconds, 1),
            "example": {"gaps_deg": list(example.gaps), "interval": list(example.interval),
                        "median": example.median, "grid": example.grid.tolist(),
                        "density": example.density.tolist()}}


def plot(values: np.ndarray, curves: dict, rows: list[dict], trip: dict, path: Path) -> Path:
    """Gap ratios against ΔN(30°) with the thesis intervals; the round trip's example posterior."""
    from uqdrape.report.figures import panels, save

    fig, (ax, bx) = panels(2, size=(5.6, 4.4))
    colours = dict(zip(curves, ("tab:blue", "tab:cyan", "tab:orange", "tab:red")))
    for label, (r252, r378) in curves.items():
        ax.plot(values, r252, "--", color=colours[label], lw=1.2)
        ax.plot(values, r378, "-", color=colours[label], lw=1.5, label=label)
    for row in rows:
        label = f"{row['model']}, mu {row['friction']}"
        ax.axvspan(row["lower_Fs_L"], row["upper_Fs_L"], color=colours[label], alpha=0.15)
    ax.axhline(0.1, color="0.3", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.set_xlabel("card imbalance dN(30 deg) = N+ - N- (N/m, F_s/L)")
    ax.set_ylabel("gap(F) / gap(0 N): solid 378 N, dashed 252 N")
    ax.set_title("Thesis: not symmetric at 252 N, symmetric at 378 N\n(shaded: dN(30) it allows; dotted: 10 %)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, title="blank-holder model, friction", title_fontsize=8)
    ex = trip["example"]
    bx.plot(ex["grid"], ex["density"], color="k")
    bx.axvspan(*ex["interval"], color="tab:green", alpha=0.2, label="95 % interval")
    bx.axvline(trip["truth_Fs_L"], color="tab:red", lw=1.5, label=f"truth {trip['truth_Fs_L']:g} N/m")
    bx.set_xscale("log")
    bx.set_xlim(trip["truth_Fs_L"] / 3.0, trip["truth_Fs_L"] * 3.0)
    bx.set_xlabel("dN(30 deg) (N/m, F_s/L; the prior spans 1-100)")
    bx.set_ylabel("posterior density per unit ln dN")
    bx.set_title(f"Round trip: one trial (radial, mu 0.2); intervals cover the truth\n"
                 f"in {trip['covered']} of {trip['repeats']} trials")
    bx.legend(fontsize=8)
    bx.grid(True, which="both", alpha=0.3)
    return save(fig, path)


def readme(rows: list[dict], like: dict, trip: dict) -> str:
    def fmt(v):
        return "open" if v is None else f"{v:.3g}"

    lines = ["# What the thesis's nose-cone trial says about the card", "",
             "Written by `python tools/card_imbalance.py` (generated output). Card family: `ebxhd936_derived` with",
             "its mid-angle imbalance dN(30 deg) = N+(30) - N-(30) moved, its ends kept",
             "(`uqdrape.material.imbalance`); mould and net of the gallery study "
             "`nosecone-blankholder-levels-architecture`.",
             "The statements: not yet symmetric at 252 N, symmetric at 378 N (gap down to 10 % of its 0 N value).",
             "", "![gap ratios and round trip](imbalance.png)", "",
             "| blank-holder model | friction | dN(30) as F_s/L (N/m) | dN(30) as F/L (N/m) |", "|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['model']} | {r['friction']} | ({fmt(r['lower_Fs_L'])}, {fmt(r['upper_Fs_L'])}] | "
                     f"({fmt(r['lower_F_L'])}, {fmt(r['upper_F_L'])}] |")
    lines += ["", f"The card as derived has dN(30) = 6.65 N/m (F_s/L). The picture-frame-scale card "
                  f"`{like['card']}` (dN(30) = {like['own_dN30_Fs_L']:.4g} N/m, an assumed mid-range) keeps its assumed "
                  f"end imbalance in this family: even at dN(30) = 0.5 N/m its 378 N gap is "
                  f"{like['gap_ratio_378N_at_0.5']:.0%} of the 0 N gap (radial, mu 0.2), so no mid-angle value makes "
                  "it symmetric there; the trial then constrains its high-angle imbalance too.", "",
              f"Round trip: trials with dN(30) = {trip['truth_Fs_L']:g} N/m at {trip['forces_N']} N, one part per force "
              f"(zero-angle scatter sd {trip['zero_angle_sd_deg']:g} deg per cell), each gap read to "
              f"{trip['read_sd_deg']:g} deg: the 95 % interval covered the truth in {trip['covered']} of "
              f"{trip['repeats']} trials (median interval {trip['median_interval'][0]:.3g} - "
              f"{trip['median_interval'][1]:.3g} N/m; model {trip['model_drapes']} drapes, "
              f"{trip['model_seconds']} s)."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python tools/card_imbalance.py", description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200, help="round-trip trials (default 200)")
    args = parser.parse_args(argv)
    if not (ROOT / "studies").is_dir():
        print(f"card_imbalance: error: {ROOT} has no studies/ folder; run from a uqdrape checkout", file=sys.stderr)
        return 2
    with contextlib.chdir(ROOT):
        cfg = settings()
        rows = thesis_table(cfg)
        values = np.geomspace(1.0, 100.0, 21)
        curves = ratio_curves(cfg, values)
        like = like_family(cfg)
        trip = round_trip(cfg, args.repeats)
        OUT.mkdir(parents=True, exist_ok=True)
        png = plot(values, curves, rows, trip, OUT / "imbalance.png")
        record = {"thesis_table": rows, "ratio_curves": {"dN30_Fs_L": values.tolist(), **curves},
                  "like_family": like, "round_trip": {k: v for k, v in trip.items() if k != "example"}}
        (OUT / "imbalance.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
        (OUT / "README.md").write_text(readme(rows, like, trip), encoding="utf-8")
    print(f"card_imbalance: wrote {ROOT / OUT} ({png.name}, imbalance.json, README.md)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
