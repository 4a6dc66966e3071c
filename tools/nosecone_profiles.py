"""Does the nose cone's shape explain the force the PF-scale card needs? (issue 24)

``python tools/nosecone_profiles.py`` computes the symmetrising blank-holder force
(``uqdrape.symmetry``: where the - minus + quadrant gap falls to 10 % of its 0 N value)
of the PF-scale card ``ebxhd936_like`` over plausible nose-cone profiles, with both
blank-holder models, and writes ``results/gallery/nosecone-profiles/`` (profiles.json,
profiles.csv, profiles.png). Every other setting (spacing 5 mm, 30 rings, mu 0.2,
orientation, solver tolerances) is that of the gallery studies
``nosecone-blankholder-levels`` (radial) and ``-slip``; only the mould changes.

The thesis (Wiggers 2007, ch. 5) gives no nose-cone dimensions, so the profiles span
what a nose cone of about 225 mm base radius (its plan outlines) could be:

* the analytic ``nose_cone`` (sphere-tipped cone on a flange, base radius 225 mm) at
  cone half-angles 25-45 deg and tip radii 25, 50, 100 mm (the height follows);
* a tangent ogive and a half-ellipsoid of the default cone's base radius and height
  (225 mm, 284.2 mm), revolved with trimesh and draped as ``kind = "mesh"``;
* the default cone revolved the same way, to measure what meshing alone changes.

Meshes: meridian steps of at most ``STEP_MM`` (arc length), ``SECTIONS`` sections around
(circumferential edge 2 pi 225 / SECTIONS = 1.96 mm at the base), a flat flange out to
twice the base radius; the mesh files are written to a temporary folder (regenerated in
a second). A script of the checkout, like tools/gallery.py.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = Path("results") / "gallery" / "nosecone-profiles"
#: The gallery studies whose settings every drape here takes, by blank-holder model.
STUDIES = {"radial": Path("studies") / "nosecone-blankholder-levels.toml",
           "slip": Path("studies") / "nosecone-blankholder-levels-slip.toml"}
#: Largest meridian edge of a revolved mesh (mm, arc length).
STEP_MM = 2.0
#: Sections around the axis of a revolved mesh (0.5 deg each).
SECTIONS = 720
#: Flange of a revolved mesh: out to this multiple of the base radius, radial step (mm).
FLANGE_FACTOR, FLANGE_STEP_MM = 2.0, 10.0
#: Cone half-angles (deg) and tip radii (mm) of the analytic nose cones.
HALF_ANGLES = (25.0, 30.0, 35.0, 40.0, 45.0)
TIP_RADII = (25.0, 50.0, 100.0)
#: The thesis's experimental band (N): "almost symmetric at 252 N, entirely at 378 N".
THESIS_BAND = (252.0, 378.0)
#: Upper end of the force search (N): far beyond the press, so "how far off" is measured.
F_MAX = 1e5


# ----------------------------------------------------------------------------- profiles


def ogive_rho(base_radius: float, height: float) -> float:
    """Radius (mm) of the circular arc of a tangent ogive of base radius R and height H."""
    return (base_radius**2 + height**2) / (2.0 * base_radius)


def ogive_meridian(base_radius: float, height: float, n: int) -> np.ndarray:
    """n points (r, z) mm of a tangent ogive's meridian from its apex (0, H) to its base (R, 0):
    the arc of radius rho centred at (R - rho, 0), evenly spaced in arc length; the wall is
    vertical at the base (tangent to the cylinder r = R)."""
    rho = ogive_rho(base_radius, height)
    phi = np.linspace(math.asin(height / rho), 0.0, n)
    pts = np.c_[(base_radius - rho) + rho * np.cos(phi), rho * np.sin(phi)]
    pts[0] = 0.0, height
    pts[-1] = base_radius, 0.0
    return pts


def ellipse_meridian(base_radius: float, height: float, n: int) -> np.ndarray:
    """n dense points (r, z) mm of a half-ellipsoid's meridian r = R sin t, z = H cos t from
    its apex (0, H) to its base (R, 0) (even in t; :func:`resample` evens the arc length)."""
    t = np.linspace(0.0, 0.5 * math.pi, n)
    pts = np.c_[base_radius * np.sin(t), height * np.cos(t)]
    pts[-1] = base_radius, 0.0
    return pts


def nosecone_meridian(cone, n: int) -> np.ndarray:
    """n dense points (r, z) mm of an analytic ``NoseCone``'s meridian, apex to base: the
    spherical tip to the blend radius, then the tangent cone."""
    a = math.radians(cone.half_angle_deg)
    zc = cone.tip_height - cone.tip_radius
    psi = np.linspace(0.0, 0.5 * math.pi - a, n // 4)  # polar angle on the tip sphere
    tip = np.c_[cone.tip_radius * np.sin(psi), zc + cone.tip_radius * np.cos(psi)]
    r = np.linspace(cone.blend_radius, cone.base_radius, n - n // 4)[1:]
    wall = np.c_[r, cone.height(r, np.zeros_like(r))]
    pts = np.r_[tip, wall]
    pts[-1] = cone.base_radius, 0.0
    return pts


def resample(points: np.ndarray, step: float) -> np.ndarray:
    """The polyline ``points`` (n, 2) resampled at even arc length, at most ``step`` mm
    apart, keeping both ends."""
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(points, axis=0).T))]
    m = max(math.ceil(s[-1] / step), 1) + 1
    t = np.linspace(0.0, s[-1], m)
    return np.c_[np.interp(t, s, points[:, 0]), np.interp(t, s, points[:, 1])]


def revolve(meridian: np.ndarray, *, step: float = STEP_MM, sections: int = SECTIONS):
    """A trimesh sheet of the meridian (r, z) mm (apex first, base on z = 0 last) revolved
    about z, resampled at ``step``, with the flat flange out to FLANGE_FACTOR x the base
    radius; an open sheet facing +z (uqdrape.geometry.MeshSurface winds it so)."""
    import trimesh

    wall = resample(meridian, step)
    base = wall[-1, 0]
    k = max(math.ceil((FLANGE_FACTOR - 1.0) * base / FLANGE_STEP_MM), 1)
    flange = np.c_[np.linspace(base, FLANGE_FACTOR * base, k + 1)[1:], np.zeros(k)]
    return trimesh.creation.revolve(np.r_[wall, flange], sections=sections)


def ogive_mesh(base_radius: float, height: float, *, step: float = STEP_MM, sections: int = SECTIONS):
    """The revolved tangent ogive (see :func:`revolve`)."""
    return revolve(ogive_meridian(base_radius, height, 4000), step=step, sections=sections)


def ellipsoid_mesh(base_radius: float, height: float, *, step: float = STEP_MM, sections: int = SECTIONS):
    """The revolved half-ellipsoid (see :func:`revolve`)."""
    return revolve(ellipse_meridian(base_radius, height, 20000), step=step, sections=sections)


def ogive_distance(points: np.ndarray, base_radius: float, height: float) -> np.ndarray:
    """Distance (mm) of points (n, 3) from the tangent ogive (exact near its wall: the
    distance of (r, z) from the meridian's circle)."""
    rho = ogive_rho(base_radius, height)
    r = np.hypot(points[:, 0], points[:, 1])
    return np.abs(np.hypot(r - (base_radius - rho), points[:, 2]) - rho)


def ellipsoid_distance(points: np.ndarray, base_radius: float, height: float) -> np.ndarray:
    """Distance (mm) of points (n, 3) from the half-ellipsoid, to first order: |F| / |grad F|
    with F = (r / R)^2 + (z / H)^2 - 1 (relative error of the order of distance / radius)."""
    r = np.hypot(points[:, 0], points[:, 1])
    z = points[:, 2]
    f = (r / base_radius) ** 2 + (z / height) ** 2 - 1.0
    g = np.hypot(2.0 * r / base_radius**2, 2.0 * z / height**2)
    return np.abs(f) / g


def wall_error(mesh, distance) -> float:
    """Largest distance (mm) of the face centroids of the wall (z > 0) from the analytic
    surface (``distance``: points -> mm): the mesh's chord error."""
    c = mesh.triangles_center
    return float(distance(c[c[:, 2] > 1e-9]).max())


# ----------------------------------------------------------------------------- drapes


@dataclasses.dataclass(frozen=True)
class Profile:
    """One mould: a label for the table and plot, its family, its shape in words, and the
    [geometry] it is draped as (kind and parameters; a mesh's path filled in at run time)."""

    label: str
    family: str
    shape: str
    kind: str
    params: dict


def profiles(mesh_dir: Path) -> tuple[list[Profile], dict]:
    """The profiles draped, and the revolved meshes' data (file, edge lengths, chord error)."""
    from uqdrape.geometry import NoseCone

    base = NoseCone()
    out = []
    for t in TIP_RADII:
        for a in HALF_ANGLES:
            cone = NoseCone(half_angle_deg=a, tip_radius=t)
            out.append(Profile(f"cone {a:g} deg, tip {t:g} mm", "cone",
                               f"half-angle {a:g} deg, tip radius {t:g} mm, base radius {cone.base_radius:g} mm, "
                               f"height {cone.tip_height:.1f} mm", "nose_cone", {"half_angle_deg": a, "tip_radius": t}))
    R, H = base.base_radius, base.tip_height
    meshes = {}
    for label, mesh, distance in (
            ("tangent ogive", ogive_mesh(R, H), lambda p: ogive_distance(p, R, H)),
            ("half-ellipsoid", ellipsoid_mesh(R, H), lambda p: ellipsoid_distance(p, R, H)),
            ("cone 35 deg, tip 50 mm, meshed", revolve(nosecone_meridian(base, 20000)), None)):
        path = mesh_dir / f"{label.split(',')[0].replace(' ', '_')}.stl"
        mesh.export(path)
        edges = mesh.edges_unique_length
        on_wall = mesh.vertices[mesh.edges_unique].min(1)[:, 2] > 0
        meshes[label] = {"faces": len(mesh.faces), "edge_length_mm_max": round(float(edges.max()), 3),
                         "edge_length_mm_wall_max": round(float(edges[on_wall].max()), 3),
                         "chord_error_mm": None if distance is None else float(f"{wall_error(mesh, distance):.3g}")}
        family = "mesh control" if label.endswith("meshed") else "mesh"
        shape = (f"base radius {R:g} mm, height {H:.1f} mm (the default cone's)" if family == "mesh"
                 else "the default analytic cone, revolved as the meshes are")
        out.append(Profile(label, family, shape, "mesh", {"path": str(path)}))
    return out, meshes


def settings(model: str) -> dict:
    """The drape settings of the gallery study of blank-holder ``model`` (all but the mould)."""
    from uqdrape.study import load_study

    st = load_study(STUDIES[model])
    f, s, p = st.fabric, st.solver, st.process
    return {"material": f.material, "spacing": f.spacing_mm, "rings": s.rings,
            "kwargs": {"friction": p.friction, "blankholder_model": p.blankholder_model,
                       "orientation": f.orientation_deg, "pre_shear": f.pre_shear_deg, "skew": f.skew_deg,
                       "crossover": tuple(f.crossover), "tolerance": s.tolerance_deg,
                       "max_iterations": s.max_iterations}}


def run(profile: Profile, model: str) -> dict:
    """The symmetrising force of ``profile`` under blank-holder ``model`` (one row), and the
    mean signed shear (deg) of the + and - max-shear lines at 0 N (nodes 1..k_max), which
    says how hard the profile shears the fabric."""
    from uqdrape.drape import drape
    from uqdrape.geometry import build
    from uqdrape.material import load_material
    from uqdrape.stats import line_scalars
    from uqdrape.symmetry import symmetrising_force

    cfg = settings(model)
    surface = build(profile.kind, **profile.params)
    material = load_material(cfg["material"])
    t0 = time.perf_counter()
    row = {"profile": profile.label, "family": profile.family, "shape": profile.shape, "model": model,
           "material": cfg["material"], "spacing_mm": cfg["spacing"], "rings": cfg["rings"],
           "friction": cfg["kwargs"]["friction"]}
    try:
        found = symmetrising_force(surface, cfg["spacing"], cfg["rings"], material,
                                   f_max=F_MAX, **cfg["kwargs"])
    except ValueError as err:  # the max-shear lines not valid to k_max at some force
        row.update(force_N=None, note=str(err))
    else:
        lines = line_scalars(drape(surface, cfg["spacing"], cfg["rings"], mode="energy", material=material,
                                   blankholder_force=0.0, **cfg["kwargs"]), found.k_max)
        row.update(force_N=None if found.force is None else round(found.force, 1),
                   bracket_N=[round(b, 1) if b is not None else None for b in found.bracket],
                   gap0_deg=round(found.gap0, 3), k_max=found.k_max,
                   plus_line_shear0_deg=round(float(lines["plus_mean_shear"].item()), 2),
                   minus_line_shear0_deg=round(float(lines["minus_mean_shear"].item()), 2),
                   gap_at_thesis_deg={f"{f:g}": round(found.gap_at(f), 3) for f in (126.0, 252.0, 378.0)},
                   note=found.describe())
    row["seconds"] = round(time.perf_counter() - t0, 1)
    return row


# ----------------------------------------------------------------------------- outputs


def gallery_forces() -> dict:
    """The gallery's symmetrising forces of the default cone (headline.json of the
    nosecone-blankholder-levels entries), by blank-holder model, for the cross-check."""
    out = {}
    for model, study in STUDIES.items():
        path = Path("results") / "gallery" / study.stem / "headline.json"
        head = json.loads(path.read_text(encoding="utf-8"))["headline"]
        out[model] = head["symmetrising force, gap down to 10 % of 0 N (N)"]
    return out


def plot(rows: list[dict], path: Path) -> None:
    """Symmetrising force against profile, both models, the thesis band shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = list(dict.fromkeys(r["profile"] for r in rows))
    x = np.arange(len(labels))
    fig, ax = plt.subplots(figsize=(11, 5.5), layout="constrained")
    ax.axhspan(*THESIS_BAND, color="tab:green", alpha=0.25, label="thesis: symmetric at 252-378 N (measured)")
    for model, marker, colour in (("radial", "o", "tab:blue"), ("slip", "s", "tab:orange")):
        y = [next(r["force_N"] for r in rows if r["profile"] == lab and r["model"] == model) for lab in labels]
        y = np.array([np.nan if v is None else v for v in y], float)
        ax.plot(x, y, marker, color=colour, ms=7, label=f"{model} blank-holder model")
    for k, lab in enumerate(labels):
        if lab.startswith("cone 35 deg, tip 50 mm"):
            ax.axvline(k, color="0.6", lw=0.8, ls=":")
    ax.set_yscale("log")
    ax.set_xticks(x, labels, rotation=55, ha="right", fontsize=8)
    ax.set_ylabel("symmetrising force (N): gap down to 10 % of 0 N")
    ax.set_title("Nose-cone profile vs the force that makes the drape symmetric\n"
                 "card ebxhd936_like (PF scale), mu 0.2, 5 mm, 30 rings; dotted: the gallery's default cone")
    ax.grid(True, which="both", axis="y", alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_csv(rows: list[dict], path: Path) -> None:
    keys = ["profile", "family", "model", "material", "force_N", "gap0_deg", "plus_line_shear0_deg",
            "minus_line_shear0_deg", "k_max", "seconds", "shape"]
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python tools/nosecone_profiles.py", description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(STUDIES), choices=list(STUDIES))
    args = parser.parse_args(argv)
    if not (ROOT / "studies").is_dir():
        print(f"nosecone_profiles: error: {ROOT} has no studies/ folder; run from a uqdrape checkout", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    with contextlib.chdir(ROOT), tempfile.TemporaryDirectory() as tmp:
        todo, meshes = profiles(Path(tmp))
        rows = []
        for profile in todo:
            for model in args.models:
                rows.append(run(profile, model))
                r = rows[-1]
                print(f"nosecone_profiles: {r['profile']:<34} {model:<6} {r['force_N']} N ({r['seconds']} s)",
                      file=sys.stderr)
        OUT.mkdir(parents=True, exist_ok=True)
        record = {"what": "symmetrising blank-holder force (uqdrape.symmetry, gap down to 10 % of 0 N) by nose-cone "
                          "profile; settings of the studies named, only the mould changed",
                  "studies": {m: STUDIES[m].as_posix() for m in args.models},
                  "thesis_band_N": list(THESIS_BAND), "f_max_N": F_MAX,
                  "mesh": {"meridian_step_mm": STEP_MM, "sections": SECTIONS, "flange_factor": FLANGE_FACTOR,
                           "flange_step_mm": FLANGE_STEP_MM, "meshes": meshes},
                  "gallery_default_cone": gallery_forces(),
                  "seconds_total": round(time.perf_counter() - t0, 1), "rows": rows}
        (OUT / "profiles.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
        write_csv(rows, OUT / "profiles.csv")
        plot(rows, OUT / "profiles.png")
    print(f"nosecone_profiles: wrote {OUT} in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
