"""The reference gallery: every thesis-figure study run end to end, its small report kept.

``python tools/gallery.py [--only NAME ...] [--workers N]`` runs each study of
:data:`GALLERY` from the checkout's ``studies/`` (ensemble under ``results/<name>/``, as
``uqdrape run`` would), writes its report and copies the report -- the PNGs its page links, ``index.html``,
``summary.json``, not the netCDF chunks; a design study's ``design.nc`` too -- into
``results/gallery/<name>/``, plus the
entry's headline numbers in ``headline.json`` and, for entries with ``exports``, its
VTK and flat-pattern export in ``export/`` (a laminate entry with ``fe_mesh``: its FE
handoff there; its plies' own reports in ``ply-NAME/``). ``results/gallery/README.md`` is then
rebuilt from the headline files of all entries present, so ``--only`` refreshes one entry.

The PNGs are the report's own lossless ones. Paths are relative to the checkout root
(the folder holding ``studies/``), whatever the current directory, so the stored study
records carry the relative output folder and the gallery is reproducible on any machine.
A script of the checkout, not of the installed package: it needs ``studies/`` beside
it. ``results/gallery/`` is generated output, not kept in git (the documentation's
validation page quotes its headline numbers and a few of its figures).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.stats import spearmanr

from uqdrape.stats import inner_outer_sd, line_scalars, line_statistics, node_statistics, wrinkle_risk

ROOT = Path(__file__).resolve().parent.parent
#: Where the committed reference reports live, relative to the checkout root.
GALLERY_DIR = Path("results") / "gallery"
#: Report files kept in the gallery besides the figures the page links (everything else of
#: a run stays in results/<name>/, including PNGs an older report left in its folder).
KEPT = ("index.html", "summary.json")
#: Rings at each end of the net summarised by ``inner_outer_sd``.
RING_BAND = 5


# ----------------------------------------------------------------------------- headline numbers


def _round(value: float, digits: int = 3) -> float:
    return float(f"{value:.{digits}g}")


def _skew_headline(ds: xr.Dataset) -> dict:
    """The sampled skews' extremes, their rank correlation, and the Fig 5.6 check: the
    study's drape at exactly 0 and 55 deg (tests/test_energy_drape.py asserts the same)."""
    from uqdrape.drape import drape
    from uqdrape.study import load_study

    skew = ds["skew"].values.ravel()  # one force level
    energy = ds["energy_blankholder"].values.ravel()
    lo, hi = int(np.argmin(skew)), int(np.argmax(skew))
    st = load_study(ENTRIES["hemisphere-skew"].study)
    exact = drape(st.geometry.build_mould(), st.fabric.spacing_mm, st.solver.rings, skew=[0.0, 55.0],
                  blankholder_force=st.force_levels[0], friction=st.process.friction,
                  blankholder_model=st.process.blankholder_model)["energy_blankholder"].values
    return {f"E_BH total at skew {skew[lo]:.1f} deg (J)": _round(energy[lo]),
            f"E_BH total at skew {skew[hi]:.1f} deg (J)": _round(energy[hi]),
            "Spearman rank correlation of E_BH with skew": _round(float(spearmanr(skew, energy).statistic)),
            "Fig 5.6 check, E_BH at skew 0 / 55 deg exactly (J; thesis axis 0-7 J)":
                f"{exact[0]:.3f} / {exact[1]:.3f}"}


def _sweep_headline(ds: xr.Dataset) -> dict:
    asym = line_scalars(ds)["asymmetry"].mean("realization")
    out = {f"asymmetry (+ plus - line means) at {float(f):g} N (deg)": _round(float(asym.sel(blankholder_force=f)))
           for f in ds["blankholder_force"].values[[0, -1]]}
    return out


def _levels_headline(ds: xr.Dataset) -> dict:
    """The -/+ quadrant gap at each force level and the symmetrising force (uqdrape.symmetry),
    draped again with the study's own mould, material, blank-holder model and settings."""
    from uqdrape.geometry import build
    from uqdrape.material import load_material
    from uqdrape.symmetry import symmetrising_force

    study = json.loads(ds.attrs["study_json"])
    fabric, solver, process = study["fabric"], study["solver"], study["process"]
    geometry = dict(study["geometry"])
    surface = build(geometry.pop("kind"), **geometry)
    found = symmetrising_force(
        surface, fabric["spacing_mm"], solver["rings"], load_material(fabric["material"]),
        friction=process["friction"], blankholder_model=process["blankholder_model"],
        orientation=fabric["orientation_deg"], pre_shear=fabric["pre_shear_deg"], skew=fabric["skew_deg"],
        crossover=tuple(fabric["crossover"]), tolerance=solver["tolerance_deg"],
        max_iterations=solver["max_iterations"])
    gap = -line_scalars(ds, found.k_max)["asymmetry"].mean("realization")
    out = {"material card": fabric["material"], "blank-holder model": process["blankholder_model"],
           "friction": process["friction"]}
    out.update({f"gap - minus + quadrants at {float(f):g} N (deg)": _round(float(gap.sel(blankholder_force=f)))
                for f in ds["blankholder_force"].values})
    out["symmetrising force, gap down to 10 % of 0 N (N)"] = (
        f"{found.force:.0f} (bracket {found.bracket[0]:.0f}-{found.bracket[1]:.0f})" if found.reached
        else f"not reached below {found.f_max:g}")
    return out


def _sweep_scatter_headline(ds: xr.Dataset) -> dict:
    out = _sweep_headline(ds)
    sd = line_statistics(ds)["shear_sd"].sel(k=slice(1, None)).max(("quadrant", "k"))
    for f in ds["blankholder_force"].values[[0, -1]]:
        out[f"max sd along the max-shear lines at {float(f):g} N (deg)"] = _round(float(sd.sel(blankholder_force=f)))
    return out


def _node6_headline(ds: xr.Dataset) -> dict:
    st = line_statistics(ds).sel(k=6).isel(blankholder_force=0)  # one force level
    out = {}
    for q, text in (("++", "+"), ("-+", "-")):
        s = st.sel(quadrant=q)
        out[f"node 6, {text} quadrant {q}: shear mean / sd (deg)"] = (
            f"{float(s['shear_mean']):.1f} / {float(s['shear_sd']):.2f}")
        out[f"node 6, {text} quadrant {q}: distance from the tip (mm)"] = _round(float(s["distance_mean"]))
    return out


def _twin_headline(ds: xr.Dataset, out: Path) -> dict:
    """A hierarchical run's widening as its report states it (measured against its fixed
    twin, ``uqdrape.workflow.twin``): the median over the nodes that move."""
    from uqdrape.workflow.twin import BAND_WIDER, DRAWN_SD, SD_WIDER, SHARE

    extra = json.loads((out / "report" / "summary.json").read_text(encoding="utf-8"))["extra"]
    out = {f"{DRAWN_SD}, median": extra[DRAWN_SD]["value"]}
    out.update((f"{row}, median over the nodes", extra[row]["value"]) for row in (SD_WIDER, BAND_WIDER, SHARE))
    return out


def _plate_headline(ds: xr.Dataset) -> dict:
    inner, outer = inner_outer_sd(ds, band=RING_BAND)
    n = int(ds.attrs["rings"])
    pooled = float(ds["shear"].std(skipna=True))
    return {f"shear sd, rings 1-{RING_BAND} (deg)": _round(inner),
            f"shear sd, rings {n - RING_BAND}-{n - 1} (deg)": _round(outer),
            "pooled sd of all node shears (deg; thesis fit 11.04)": _round(pooled),
            "mean node shear (deg; 0 without noise)": _round(float(ds["shear"].mean(skipna=True)))}


def _wrinkle_headline(ds: xr.Dataset) -> dict:
    ex = wrinkle_risk(ds)
    p = ex["probability"]
    top = ex.isel(p.argmax(...))
    return {f"max {ex.attrs['risk']}": (
                f"{float(top['probability']):.2f} [{float(top['probability_lower']):.2f}, "
                f"{float(top['probability_upper']):.2f}] at node ({int(top['i'])}, {int(top['j'])})"),
            "nodes with P > 0.05": int((p > 0.05).sum())}


def _mesh_headline(ds: xr.Dataset) -> dict:
    """A mesh mould's ensemble per force level: the largest |mean| and sd of node shear, the
    largest wrinkle risk, and how much of the net hangs below the top (on walls, z < -1 mm)."""
    st, risk = node_statistics(ds), wrinkle_risk(ds)
    below = float((ds["z"].mean("realization") < -1.0).mean())
    out = {"share of the net's nodes below the top (on walls)": _round(below)}
    for f in ds["blankholder_force"].values:
        level = {"blankholder_force": f}
        out[f"max |mean shear| / max sd at {float(f):g} N (deg)"] = (
            f"{_round(float(abs(st['mean'].sel(level)).max()))} / {_round(float(st['sd'].sel(level).max()))}")
        if risk is not None:
            p = risk["probability"].sel(level)
            out[f"max {risk.attrs['risk']} at {float(f):g} N; nodes with P > 0.5"] = (
                f"{float(p.max()):.2f}; {int((p > 0.5).sum())}")
    return out


def _design_headline(ds: xr.Dataset) -> dict:
    """The design's optimum and its objective on the validation sample against the
    baseline (and, for sectors, the uniform force at the same total), from design.nc."""
    val = json.loads(ds.attrs["validation"])
    name, statistic = ds.attrs["objective"], ds.attrs["statistic"]
    n = sum(v != "friction" for v in np.atleast_1d(ds.attrs["variables"]))

    def triple(e):
        return f"{e[0]:.3g} [{e[1]:.3g}, {e[2]:.3g}]"

    optimum = np.atleast_1d(ds.attrs["optimum"])
    if n > 1:
        forces = " / ".join(f"{f:.0f}" for f in optimum[:n]) + f" (total {optimum[:n].sum():.0f})"
    else:
        lo, hi = (float(np.atleast_1d(ds.attrs[k])[0]) for k in ("optimum_lower", "optimum_upper"))
        forces = f"{optimum[0]:.0f} [{lo:.0f}, {hi:.0f}]"
    out = {"optimum force(s) (N)": forces}
    for role in ("optimum", "uniform", "baseline"):
        if role in val:
            total = sum(val[role]["x"][:n])
            out[f"{name} of the {role} ({total:.0f} N), validation"] = triple(val[role]["estimate"])
    out["validation estimate within the optimisation estimate's limits"] = "yes" if ds.attrs["validated"] else "no"
    if "margin" in ds.attrs:
        m = json.loads(ds.attrs["margin"])["validation"]
        out["uniform minus sector, validation (paired bootstrap)"] = (
            f"{triple(m)}: the sector design {'beats' if m[1] > 0 else 'does not beat'} the uniform force")
    designs = int((ds["sample"] == "design").sum())
    out["designs x drapes (+ validation)"] = (f"{designs} x {ds.attrs['design_realizations']} "
                                             f"(+ {len(val)} x {ds.attrs['validation_realizations']})")
    out["objective"] = f"{statistic} of {name}" + (f", target {ds.attrs['target']:g}" if ds.attrs["target"] != "none"
                                                   else "")
    return out


def _sensitivity_headline(ds: xr.Dataset, out: Path) -> dict:
    from uqdrape.workflow import open_sensitivity

    indices = open_sensitivity(out)[0]
    out_ = {}
    for factor, qoi in (("friction", "blankholder_energy"), ("zero_angle", "asymmetry"), ("friction", "asymmetry")):
        st = indices["ST"].sel(factor=factor, qoi=qoi)
        values = ", ".join(f"{float(v):.2f}" for v in st.values)
        out_[f"ST of {factor} for {qoi} at {', '.join(f'{f:g}' for f in st.blankholder_force.values)} N"] = values
    return out_


def _laminate_headline(ds: xr.Dataset) -> dict:
    """P(any ply locked) with its 95 % Wilson interval and each ply's P(locked), per force level."""
    from uqdrape.schema import FORCE, PLY, PLY_ANGLE
    from uqdrape.stats import laminate_lock

    lock = laminate_lock(ds)
    out = {}
    for force in ds[FORCE].values:
        at = lock.sel({FORCE: force})
        out[f"P(any ply locked) at {force:g} N, 95 % interval"] = (
            f"{float(at['p_any']):.3f} [{float(at['lower']):.3f}, {float(at['upper']):.3f}] "
            f"({int(at['count'])} of {lock.attrs['n']})")
        out[f"P(ply locked) at {force:g} N"] = ", ".join(
            f"{p} ({float(ds[PLY_ANGLE].sel({PLY: p})):+g} deg) {float(at['p_ply'].sel({PLY: p})):.3f}"
            for p in ds[PLY].values)
    return out


@dataclass(frozen=True)
class Entry:
    """One gallery study: its name (= the study file's stem and its [study] name), the
    thesis figure it reproduces, the report picture the README shows, its headline numbers
    (from the ensemble) and what the thesis reports to compare them with."""

    name: str
    figure: str
    picture: str
    headline: Callable[..., dict]
    thesis: str
    #: the headline also reads the run folder (e.g. its sensitivity.nc), not only the ensemble
    reads_folder: bool = False
    #: ship the ensemble's export too: VTK net statistics and mould, flat pattern, a render
    exports: bool = False
    #: a laminate's FE handoff on this shell mesh (relative to the checkout root): ply
    #: thickness 0.25 mm, FE_DECKS Monte Carlo decks, Abaqus, LS-DYNA and Nastran
    fe_mesh: str | None = None

    @property
    def study(self) -> Path:
        return Path("studies") / f"{self.name}.toml"


GALLERY = (
    Entry("hemisphere-skew", "Figs 5.5/5.6", "vs_skew.png", _skew_headline,
          "total blank-holder energy rises as the generator paths are skewed 0-55 deg; a few J (axis to 7 J)"),
    Entry("nosecone-blankholder-levels", "Figs 5.9-5.12", "lines.png", _levels_headline,
          "the - quadrants shear more at 0 N; the gap closes with force, symmetric at 378 N; here the "
          "picture-frame-scale card, an assumed shape (see card-imbalance below)"),
    Entry("nosecone-blankholder-levels-slip", "Figs 5.9-5.12, blank-holder friction on the full slip",
          "lines.png", _levels_headline,
          "circumferential restraint not modelled (radial draw-in only); here friction on the whole slip, the "
          "picture-frame-scale card (assumed shape)"),
    Entry("nosecone-blankholder-levels-architecture", "Figs 5.9-5.12 with the ch. 4 card", "lines.png",
          _levels_headline, "almost symmetric at 252 N, entirely symmetric at 378 N (EBXhd-936, "
          "measured); here the card derived from its architecture (a model prediction) and the force that brings the "
          "gap to 10 %"),
    Entry("nosecone-blankholder-levels-architecture-slip", "Figs 5.9-5.12 with the ch. 4 card, full slip",
          "lines.png", _levels_headline, "as the entry above, blank-holder friction on the whole slip"),
    Entry("plate-spacing", "Figs 5.15/5.16", "sd_shear.png", _plate_headline,
          "fibre angles ~ Normal(45.75, 11.04 deg); the scatter grows with distance from the crossover"),
    Entry("nosecone-blankholder-sweep", "Figs 5.17/5.18", "line_statistics.png", _sweep_scatter_headline,
          "126 N, spacing sd 0.1 %: scatter like the measured one (the other levels: its future-work item 6)"),
    Entry("nosecone-zero-angle", "Figs 5.19/5.20", "line_statistics.png", _node6_headline,
          "bounded sd along the lines; node 6 at 96.6 mm (+, inter-fibre angle 33.5 deg) and 108 mm "
          "(-, 59.8 deg): its node spacing was evidently larger than 5 mm", exports=True),
    Entry("nosecone-zero-angle-hierarchical", "Figs 5.19/5.20, the sd estimated from 38 points",
          "sd_shear.png", _twin_headline, "sd 5 deg taken as known; here as read from 38 points (sd_dof 37, "
          "a sd drawn per realisation) and the limits' widening measured against the fixed-sd twin",
          reads_folder=True),
    Entry("plate-correlated-spacing", "beyond the thesis (its §5.3.3 open problem)", "sd_shear.png",
          _plate_headline, "a smooth spacing field correlated over 20 cells (100 mm) shrinks the growth of the scatter; compare plate-spacing"),
    Entry("doubledome-wrinkle-risk", "beyond the thesis (wrinkle risk)", "wrinkle_risk.png", _wrinkle_headline,
          "no wrinkling prediction (its implicit limitation); here P(a cell next to the node passes 42 deg) per node"),
    Entry("sensitivity-vs-blankholder", "beyond the thesis (its future-work items 6/7)", "sensitivity_vs_force.png",
          _sensitivity_headline, "scatter fell as blank-holder force rose, cause not modelled; here Sobol' indices "
          "per force level (20 rings, 1792 drapes per level)", reads_folder=True),
    Entry("sensitivity-vs-blankholder-30rings", "beyond the thesis (its future-work items 6/7), at its 30 rings",
          "sensitivity_vs_force.png", _sensitivity_headline, "scatter fell as blank-holder force rose, cause not "
          "modelled; here Sobol' indices per force level over the full 61 x 61 net (fields correlated over 20 mm, "
          "95 % of their variance kept; 896 drapes per level)", reads_folder=True),
    Entry("cspar-misalignment", "beyond the thesis (a tool no height field holds)", "mean_shear.png", _mesh_headline,
          "moulds are height fields there; here a C-spar (web, 10 mm fillets, 90 deg flanges) as a triangle mesh, "
          "+-45 deg fabric under ply misalignment sd 2 deg"),
    Entry("pan-corner-lock", "beyond the thesis (a tool no height field holds)", "wrinkle_risk.png", _mesh_headline,
          "here a male pan (vertical walls, 8 mm radii) as a triangle mesh: where it locks against blank-holder force"),
    Entry("design-nosecone-symmetrise", "beyond the thesis (its closing question: which pressure)", "objective.png",
          _design_headline, "'almost symmetric at 252 N, entirely symmetric at 378 N' (measured); here the least "
          "force whose upper 95 % limit of |mean asymmetry| is 1 deg under gamma0 scatter (EBXhd-936, derived card)"),
    Entry("design-doubledome-sectors", "beyond the thesis (its next step: segment-wise pressure)", "sectors.png",
          _design_headline, "segmented blank-holder pressure named as future work; here eight sector forces "
          "minimising P(lock) under an 800 N budget against the uniform force of the same total"),
    Entry("doubledome-laminate", "beyond the thesis (a laminate)", "tool_lock_map.png", _laminate_headline,
          "one ply at a time; here a quasi-isotropic [0/45/90/-45] ply book draped ply by ply, per-ply "
          "misalignment sd 1.5 deg, a common rosette error sd 1 deg: P(some ply locks) and its FE handoff",
          fe_mesh="studies/meshes/doubledome-shell.inp"),
)
ENTRIES = {e.name: e for e in GALLERY}


# ----------------------------------------------------------------------------- building


def build_entry(entry: Entry, *, workers: int | None = None, resume: bool = False, progress: bool = True) -> Path:
    """Run ``entry``'s study, write its report and copy it into the gallery; returns the
    gallery folder. Call with the checkout root as the current directory (``main`` does)."""
    from uqdrape.design import DESIGN_FILE, EVALUATIONS
    from uqdrape.ensemble import open_ensemble
    from uqdrape.study import load_study
    from uqdrape.workflow import run_report, run_study

    study = load_study(entry.study)
    if study.design is not None and not resume:  # a design resumes from its records: recompute them
        shutil.rmtree(study.output_dir / EVALUATIONS, ignore_errors=True)
    out = run_study(study, workers=workers, resume=resume, progress=progress)
    report = run_report(out).parent
    ds = xr.load_dataset(out / DESIGN_FILE) if study.design is not None else open_ensemble(out)
    headline = entry.headline(ds, out) if entry.reads_folder else entry.headline(ds)
    target = GALLERY_DIR / entry.name
    if target.exists():
        shutil.rmtree(target)
    target.mkdir(parents=True)
    copy_report(report, target)
    if study.design is not None:
        shutil.copy2(out / DESIGN_FILE, target / DESIGN_FILE)
    if entry.exports:
        export_entry(entry, out, target)
    if entry.fe_mesh is not None:
        export_fe(entry, out, target)
    record = {"study": entry.study.as_posix(), "thesis_figure": entry.figure, "thesis": entry.thesis,
              "headline": headline}
    (target / "headline.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    return target


def copy_report(report: Path, target: Path) -> None:
    """Copy a report's :data:`KEPT` files and the figures its page shows into ``target``;
    a laminate's page (its summary lists ``plies``) with each ply's own report, in
    ``target/ply-NAME/``, so the page's links hold."""
    summary = json.loads((report / "summary.json").read_text(encoding="utf-8"))
    target.mkdir(parents=True, exist_ok=True)
    for name in (*KEPT, *summary["figures"]):
        shutil.copy2(report / name, target / name)
    for ply in summary.get("plies", {}).values():
        folder = Path(ply["report"]).parent
        copy_report(report / folder, target / folder)


#: Gallery entries compared on one plot of the nose-cone asymmetry against force.
LEVEL_ENTRIES = ("nosecone-blankholder-levels", "nosecone-blankholder-levels-slip",
                 "nosecone-blankholder-levels-architecture", "nosecone-blankholder-levels-architecture-slip")
COMPARISON = "blankholder-models"


def write_level_comparison() -> Path | None:
    """Plot the gap of every level study of :data:`LEVEL_ENTRIES` in the gallery against
    blank-holder force (one line per material card and blank-holder model, from the
    entries' headline numbers) and keep the numbers; returns the PNG, or None if none is there."""
    from uqdrape.report.figures import panels, save

    series = []
    for name in LEVEL_ENTRIES:
        path = GALLERY_DIR / name / "headline.json"
        if not path.is_file():
            continue
        headline = json.loads(path.read_text(encoding="utf-8"))["headline"]
        gaps = {float(key.split(" at ")[1].split(" N")[0]): value for key, value in headline.items()
                if key.startswith("gap - minus + quadrants at ")}
        series.append({"study": name, "material": headline["material card"],
                       "blankholder_model": headline["blank-holder model"], "force_N": list(gaps),
                       "gap_deg": list(gaps.values()),
                       "symmetrising_force_N": headline["symmetrising force, gap down to 10 % of 0 N (N)"]})
    if not series:
        return None
    fig, (ax,) = panels(1, size=(6.4, 4.6))
    for line in series:
        ax.plot(line["force_N"], line["gap_deg"], marker="o",
                label=f"{line['material']}, {line['blankholder_model']} friction")
    ax.set_xlabel("blank-holder force (N)")
    ax.set_ylabel("gap: |- line mean| - |+ line mean| (deg)")
    ax.set_title("Nose cone: shear asymmetry against blank-holder force")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2, frameon=False)
    png = save(fig, GALLERY_DIR / f"{COMPARISON}.png")
    (GALLERY_DIR / f"{COMPARISON}.json").write_text(json.dumps(series, indent=2) + "\n", encoding="utf-8")
    return png


def _comparison_section() -> list[str]:
    path = GALLERY_DIR / f"{COMPARISON}.json"
    if not path.is_file():
        return []
    series = json.loads(path.read_text(encoding="utf-8"))
    forces = series[0]["force_N"]
    lines = [
        "",
        "## Blank-holder friction: radial draw-in or the whole slip",
        "",
        "The nose-cone drapes of Figs 5.9-5.12 under the thesis's blank-holder model (friction on",
        "the radial draw-in, Eq 5.1-5.5) and with friction on the whole plan slip of the held",
        "fabric (`blankholder_model = \"slip\"`). The gap is the mean |shear| along the - quadrants'",
        "max-shear lines minus that along the + quadrants' (nodes k = 1 to the last valid at 0 N),",
        "and the symmetrising force the one at which it falls to 10 % of its 0 N value (uqdrape.symmetry).",
        "",
        f"![gap against force]({COMPARISON}.png)",
        "",
        "| material card | blank-holder model | " + " | ".join(f"gap at {f:g} N (deg)" for f in forces)
        + " | symmetrising force (N) |",
        "|---|---|" + "---|" * (len(forces) + 1),
    ]
    for line in series:
        lines.append(f"| {line['material']} | {line['blankholder_model']} | "
                     + " | ".join(f"{g:.1f}" for g in line["gap_deg"]) + f" | {line['symmetrising_force_N']} |")
    return lines


def export_entry(entry: Entry, run_folder: Path, target: Path) -> list[Path]:
    """Export the entry's ensemble into ``target/export/``: ``<name>.vtu`` (per-node shear
    statistics, P(locked), fibre directions), ``<name>-mould.vtu``, the flat pattern
    (``-flat-nodes.csv``, ``-flat-outline.csv``, ``-flat.dxf``), and ``export.png``, a
    render of the exported VTK file; returns the paths."""
    from uqdrape.export import export_flat, export_vtk, levels, open_result
    from uqdrape.export.render import render_vtu

    ds, _ = open_result(run_folder)
    per_level = levels(ds, True)
    stem = target / "export" / entry.name
    vtk = export_vtk(per_level, ds, stem)
    png = render_vtu(vtk[0], target / "export" / "export.png", "shear_mean", mould_vtu=vtk[-1],
                     label="ensemble mean shear (deg)",
                     title=f"{entry.name}.vtu: mean shear over {ds.sizes['realization']} drapes, fibre 1 arrows")
    return vtk + export_flat(per_level, stem) + [png]


#: Monte Carlo decks per solver that a laminate entry's FE handoff ships.
FE_DECKS = 4


def export_fe(entry: Entry, run_folder: Path, target: Path) -> list[Path]:
    """Export a laminate entry's ensemble onto its shell mesh into ``target/export/``, as
    ``uqdrape export RUN --to fe --mesh MESH --thickness 0.25 --realizations 4`` with all
    three solvers' cards: the nominal layup decks, the Monte Carlo decks and the
    ``-laminate.nc`` samples with their Karhunen-Loeve modes; returns the paths."""
    from uqdrape.api import export_result

    paths, _ = export_result(run_folder, ["fe"], out=target / "export" / entry.name, mesh=entry.fe_mesh,
                             flavours=("abaqus", "lsdyna", "nastran"), thickness=0.25, realizations=FE_DECKS)
    return [Path(p) for p in paths]


def _cell(text: str) -> str:
    """Text for a markdown table cell (a bare | would end the cell)."""
    return text.replace("|", "\\|")


def _setup(entry: Entry) -> str:
    """What an entry's numbers rest on: its card and what the card is, its blank-holder
    model and friction (read from the study file)."""
    from uqdrape.material import load_material
    from uqdrape.study import load_study

    st = load_study(ROOT / entry.study)
    card = load_material(st.fabric.material)
    return (f"setup: card {card.name} ({card.description}), {st.process.blankholder_model} blank-holder model, "
            f"friction {st.process.friction:g}")


def write_readme() -> Path:
    """Rebuild ``results/gallery/README.md`` from the headline files of the entries present."""
    lines = [
        "# uqdrape reference gallery",
        "",
        "Small reference reports of the thesis-figure studies (Wiggers 2007, ch. 5) and studies beyond it,",
        "written by `python tools/gallery.py` (generated output: not kept in git).",
        "Each folder holds the report of `uqdrape run studies/<name>.toml` (open its `index.html`),",
        "its `summary.json` and the headline numbers below (`headline.json`). The ensembles",
        "themselves (netCDF chunks) are not kept.",
        "",
        "Entries with an `export/` folder also ship their ensemble as `uqdrape export` writes it: the net's",
        "per-node statistics and the mould as VTK (`.vtu`, open in ParaView), and the flat pattern (CSV, DXF);",
        "a laminate's `export/` holds its FE handoff on the part's shell mesh instead (`uqdrape export --to fe",
        "--thickness 0.25 --realizations 4`: Abaqus, LS-DYNA and Nastran decks, Monte Carlo decks, the netCDF",
        "of the yarn-angle samples and their Karhunen-Loeve modes).",
        "",
        "Regenerate all of it (a few minutes on 2 cores), or one entry, from the checkout root:",
        "",
        "```",
        "python tools/gallery.py            # every entry",
        "python tools/gallery.py --only plate-spacing",
        "```",
        "",
        "| entry | thesis figure and what it reports | headline numbers (this gallery) |",
        "|---|---|---|",
    ]
    for entry in GALLERY:
        path = GALLERY_DIR / entry.name / "headline.json"
        if not path.is_file():
            continue
        record = json.loads(path.read_text(encoding="utf-8"))
        numbers = "<br>".join(_cell(f"{k}: {v}") for k, v in record["headline"].items())
        lines.append(f"| [{entry.name}]({entry.name}/index.html)<br>"
                     f"[![{entry.name}]({entry.name}/{entry.picture})]({entry.name}/index.html) "
                     f"| {_cell(record['thesis_figure'])}: {_cell(record['thesis'])}<br>{_cell(_setup(entry))} "
                     f"| {numbers} |")
    lines += _comparison_section()
    lines += ["", "## Beyond a study file", "",
              "- [card-slope](card-slope/card_slope.png): the same specimen sd on cards of slope 1, 1/2 and 1/4: "
              "ring-turn and node-shear scatter against slope and blank-holder force, linearised and measured by "
              "studies that vary only the card (`python tools/card_slope.py`).",
              "- [card-imbalance](card-imbalance/README.md): the thesis's 'almost symmetric at 252 N, entirely "
              "symmetric at 378 N' as an interval of the card's mid-angle imbalance dN(30 deg), per blank-holder "
              "model, friction and force convention, and a synthetic trial calibrated back "
              "(`python tools/card_imbalance.py`).",
              "- [nosecone-profiles](nosecone-profiles/README.md): the symmetrising blank-holder force of the "
              "picture-frame-scale card over 17 nose-cone profiles, both blank-holder models "
              "(`python tools/nosecone_profiles.py`).",
              "- [sheartest-normalisation](sheartest-normalisation/synthetic_pf.png): raw picture-frame specimens, "
              "their normalised curves and the fitted card with its band (`uqdrape materials fit "
              "studies/sheartests/pf-rig.toml --plot`)."]
    shots = sorted((GALLERY_DIR / "screenshots").glob("*.png"))
    if shots:
        lines += ["", "## What a report page looks like", "",
                  "The top of report pages in headless Chromium at 1400 px (`tools/screenshot_reports.sh`):", ""]
        lines += [f"![{path.stem} report page](screenshots/{path.name})" for path in shots]
    readme = GALLERY_DIR / "README.md"
    readme.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return readme


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python tools/gallery.py",
        description="Run the gallery studies and refresh results/gallery/ (reports, headline numbers, README).")
    parser.add_argument("--only", action="append", metavar="NAME", choices=list(ENTRIES),
                        help=f"only this entry (repeatable): {', '.join(ENTRIES)}")
    parser.add_argument("--workers", type=int, help="local worker processes (default: all cores)")
    parser.add_argument("--resume", action="store_true",
                        help="reuse finished chunks of earlier runs of the same study (default: recompute)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    args = parser.parse_args(argv)
    if not (ROOT / "studies").is_dir():
        print(f"gallery: error: {ROOT} has no studies/ folder; run from a uqdrape checkout", file=sys.stderr)
        return 2
    with contextlib.chdir(ROOT):
        for entry in (ENTRIES[n] for n in args.only) if args.only else GALLERY:
            print(f"gallery: {entry.name} ({entry.figure})", file=sys.stderr)
            target = build_entry(entry, workers=args.workers, resume=args.resume, progress=not args.quiet)
            print(f"gallery: wrote {target}", file=sys.stderr)
        comparison = write_level_comparison()
        if comparison is not None:
            print(f"gallery: wrote {comparison}", file=sys.stderr)
        print(f"gallery: wrote {write_readme()}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
