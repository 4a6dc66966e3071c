"""The ``uqdrape`` command: drape | run | report | validate | materials.

Heavy imports (xarray, dask, matplotlib, SALib) happen inside the sub-commands so that
``uqdrape --help`` answers at once. Every user error is printed as one line on stderr
with exit code 2, never as a traceback.
"""

from __future__ import annotations

import argparse
import inspect
import sys
from pathlib import Path


def _geometry_help() -> str:
    from .geometry import KINDS

    lines = []
    for kind, cls in KINDS.items():
        sig = inspect.signature(cls.__init__)
        params = ", ".join(f"{p.name}={p.default!r}" if p.default is not p.empty else p.name
                           for p in list(sig.parameters.values())[1:])
        lines.append(f"  {kind:12s} {params}")
    return "\n".join(lines)


def _parse_params(pairs):
    params = {}
    for pair in pairs or []:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ValueError(f"--param expects KEY=VALUE, got {pair!r}")
        try:
            params[key] = float(value)
        except ValueError:
            params[key] = value
    return params


def cmd_drape(args) -> int:
    import numpy as np

    from .drape import drape
    from .geometry import build
    from .material import load_material
    from .report import plot_lines, plot_net

    surface = build(args.geometry, **_parse_params(args.param))
    material = load_material(args.material) if args.material else None
    ds = drape(surface, args.spacing, args.rings, orientation=args.orientation, pre_shear=args.pre_shear,
               skew=args.skew, crossover=tuple(args.crossover), mode=args.mode, material=material,
               blankholder_force=args.blankholder_force, friction=args.friction,
               blankholder_model=args.blankholder_model,
               tolerance=args.tolerance)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    nc = out.with_suffix(".nc")
    tmp = nc.with_name(nc.name + ".tmp")
    ds.to_netcdf(tmp)
    tmp.replace(nc)
    net_png = plot_net(ds, out.with_name(out.name + "-net.png"),
                       title=f"{surface.describe()}, {args.mode} drape, s = {args.spacing} mm")
    lines_png = plot_lines(ds, out.with_name(out.name + "-lines.png"))
    valid = float((ds.status == 0).mean())
    shear = ds.shear.values
    print(f"wrote {nc}, {net_png}, {lines_png}")
    print(f"valid nodes {valid:.1%}; shear {np.nanmin(shear):.1f} to {np.nanmax(shear):.1f} deg; "
          f"energy shear {float(ds.energy_shear[0]):.4g} J, blank-holder {float(ds.energy_blankholder[0]):.4g} J; "
          f"converged {bool(ds.converged[0])} ({int(ds.iterations[0])} iterations)")
    return 0


def cmd_materials(args) -> int:
    from .material import available_materials, load_material, plot_material

    if not args.name:
        for name in available_materials():
            m = load_material(name)
            print(f"{name:16s} {m.description}")
        return 0
    m = load_material(args.name)
    print(f"{m.name}: {m.description}\nlocking angle +{m.locking_angle_deg} / -{m.locking_angle_neg_deg} deg, "
          f"bending stiffness {m.bending_stiffness} N m^2\n{m.note}")
    if args.plot:
        print(f"wrote {plot_material(m, args.plot)}")
    return 0


def cmd_validate(args) -> int:
    from .study import main_validate

    return main_validate(args.files)


def cmd_run(args) -> int:
    from .ensemble import run_study
    from .report import write_run_report

    out = run_study(args.study, scheduler=args.scheduler, workers=args.workers, chunk_size=args.chunk_size,
                    resume=not args.no_resume, progress=not args.quiet, method=args.method)
    print(f"ensemble written to {out}")
    if not args.no_report:
        print(f"report: {write_run_report(out)}")
    return 0


def cmd_report(args) -> int:
    from .report import write_run_report

    print(f"report: {write_run_report(args.results, args.out)}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="uqdrape",
        description="Uncertainty quantification of kinematic drape of dry textile preforms. "
                    "Units: mm, N, J, degrees.")
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser(
        "drape", formatter_class=argparse.RawDescriptionHelpFormatter,
        help="one deterministic drape: netCDF + pictures",
        description="Drape one pin-jointed net over a mould from a crossover point and write "
                    "OUT.nc (xarray/netCDF), OUT-net.png (the net coloured by shear) and "
                    "OUT-lines.png (shear along the max-shear lines vs distance from the crossover).\n\n"
                    "Examples:\n"
                    "  uqdrape drape --geometry hemisphere --param radius=100 --spacing 5 --rings 20\n"
                    "  uqdrape drape --mode energy --material ebxhd936_like --blankholder-force 126 \\\n"
                    "      --friction 0.2 --geometry nose_cone --spacing 5 --rings 30",
        epilog="geometry kinds and their parameters (mm, degrees):\n" + _geometry_help())
    d.add_argument("--geometry", default="hemisphere", help="mould kind (see below; default hemisphere)")
    d.add_argument("--param", action="append", metavar="KEY=VALUE",
                   help="a shape parameter of the mould, repeatable (e.g. --param radius=80)")
    d.add_argument("--spacing", type=float, default=5.0, help="fibre spacing s in mm (default 5)")
    d.add_argument("--rings", type=int, default=20, help="rings n: the net has (2n+1)^2 nodes (default 20)")
    d.add_argument("--orientation", type=float, default=0.0, help="plan angle of fibre 1 from x, deg")
    d.add_argument("--pre-shear", type=float, default=0.0, help="shear of the flat blank, deg")
    d.add_argument("--skew", type=float, default=0.0,
                   help="extra angle closed between the generator paths at the crossover, deg (thesis Fig 5.5)")
    d.add_argument("--crossover", type=float, nargs=2, default=(0.0, 0.0), metavar=("X", "Y"),
                   help="first contact point in plan, mm (default 0 0)")
    d.add_argument("--mode", choices=("geodesic", "energy"), default="geodesic",
                   help="geodesic arms, or arms steered to minimise energy (needs --material)")
    d.add_argument("--material", help="material card name or path (uqdrape materials lists them)")
    d.add_argument("--blankholder-force", type=float, default=0.0, help="total blank-holder force, N")
    d.add_argument("--friction", type=float, default=0.2, help="fabric/blank-holder friction coefficient")
    d.add_argument("--blankholder-model", choices=("slip", "radial"), default="slip",
                   help="friction on the held fabric's whole plan slip (slip, default) or on the radial "
                        "draw-in only (radial, thesis Eq 5.1-5.5)")
    d.add_argument("--tolerance", type=float, default=1e-3, help="minimiser tolerance on turn angles, deg")
    d.add_argument("--out", default="results/drape/drape", help="output path stem (default results/drape/drape)")
    d.set_defaults(func=cmd_drape)

    r = sub.add_parser("run", help="run a study file: ensemble (netCDF chunks) + report",
                       description="Sample the study's uncertain inputs, drape every realisation in "
                                   "parallel with dask, store chunks under the study's output folder "
                                   "(resuming finished chunks) and write the report.")
    r.add_argument("study", help="study file (TOML), e.g. studies/nosecone-zero-angle.toml")
    r.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of an existing dask.distributed scheduler (default: local processes)")
    r.add_argument("--workers", type=int, help="local worker processes (default: all cores)")
    r.add_argument("--chunk-size", type=int, help="realisations per chunk (default: the study's)")
    r.add_argument("--method", choices=("sobol", "morris", "none"),
                   help="override the study's [sensitivity] method: 'morris' for a cheap screening run "
                        "(20 trajectories unless the study is a Morris study), 'none' for the Monte Carlo "
                        "sample; output goes to <output directory>-<method>")
    r.add_argument("--no-resume", action="store_true", help="recompute chunks that already exist")
    r.add_argument("--no-report", action="store_true", help="skip the report")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=cmd_run)

    rep = sub.add_parser("report", help="write the report of a finished run")
    rep.add_argument("results", help="a run's output folder, e.g. results/nosecone-zero-angle")
    rep.add_argument("--out", help="report folder (default RESULTS/report)")
    rep.set_defaults(func=cmd_report)

    v = sub.add_parser("validate", help="check study files without running them")
    v.add_argument("files", nargs="+", help="study files (TOML)")
    v.set_defaults(func=cmd_validate)

    m = sub.add_parser("materials", help="list material cards, or show and plot one")
    m.add_argument("name", nargs="?", help="a card name or path")
    m.add_argument("--plot", metavar="PNG", help="write the card's N_s and W curves to this PNG")
    m.set_defaults(func=cmd_materials)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError) as err:
        print(f"uqdrape {args.command}: error: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`, which closed early
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        print(f"uqdrape {args.command}: interrupted; finished chunks are kept, run again to resume",
              file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
