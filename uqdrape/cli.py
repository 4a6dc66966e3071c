"""The ``uqdrape`` command: drape | run | design | report | validate | materials | export | serve | examples.

Heavy imports (xarray, dask, matplotlib, SALib) happen inside the sub-commands so that
``uqdrape --help`` answers at once; the options' choices restate the engines' registries
(``schema.MODES``, ``export.cards.FLAVOURS``, ...; tests/test_startup.py holds them
equal). Every user error is printed as one line on stderr with exit code 2 (an I/O
failure: 3), never as a traceback. ``-q`` / ``-v`` work before or after the sub-command.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import gc
import math
import os
import shlex
import signal
import sys
import threading
import warnings
from pathlib import Path


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
    from .workflow import check_drape_inputs, drape_to_files

    options = dict(orientation=args.orientation, pre_shear=args.pre_shear, skew=args.skew,
                   crossover=tuple(args.crossover), mode=args.mode, blankholder_force=args.blankholder_force,
                   friction=args.friction, blankholder_model=args.blankholder_model, tolerance=args.tolerance)
    check_drape_inputs(args.spacing, args.rings, options, args.material)
    written, summary = drape_to_files(
        args.geometry, _parse_params(args.param), args.spacing, args.rings, args.out, material=args.material,
        progress=args.verbosity > 0, command="uqdrape " + shlex.join(args.argv), **options)
    print("wrote " + ", ".join(map(str, written)))
    print(summary)
    return 0


def cmd_card(args) -> int:
    """``materials derive ARCH --out CARD`` and ``materials fit RIG --out CARD``: a card written from a file."""
    from .workflow import derive_material, fit_material

    verb, source, make = {"derive": ("derive", "ARCH.toml", derive_material),
                          "fit": ("fit", "RIG.toml", fit_material)}[args.name]
    if not args.source:
        raise ValueError(f"{verb} needs a {'rig file' if verb == 'fit' else 'fabric architecture'}: "
                         f"uqdrape materials {verb} {source} --out CARD.toml")
    if not args.out or Path(args.out).suffix.lower() != ".toml":
        raise ValueError(f"{verb} needs --out CARD.toml (a .toml path), got {args.out!r}")
    print(make(args.source, args.out, args.plot))
    return 0


def cmd_materials(args) -> int:
    from .workflow import material_list, material_text

    if args.name in ("derive", "fit"):
        return cmd_card(args)
    if args.source or args.out:
        raise ValueError("only `uqdrape materials derive ARCH.toml --out CARD.toml` and `uqdrape materials fit "
                         "RIG.toml --out CARD.toml` take a second argument or --out")
    if args.plot is True:
        raise ValueError("--plot needs a PNG path when showing a card")
    print(_listing(material_list()) if not args.name else material_text(args.name, args.plot))
    return 0


def _listing(rows) -> str:
    """(name, description) rows as two aligned columns."""
    width = max(len(name) for name, _ in rows)
    return "\n".join(f"{name:{width}s}  {description}" for name, description in rows)


def cmd_validate(args) -> int:
    """Print each study's summary; the first invalid file ends the command (exit 2)."""
    from .workflow import describe_study, validate_study

    for name in args.files:
        print(describe_study(validate_study(name)))
    return 0


def _engine_study(args):
    """The study of ``run`` or ``design``, its output folder replaced by ``--out`` if given."""
    from .api import located

    from .workflow import check_workers

    check_workers(args.workers)
    return located(args.study, args.out or None)


def _start_workers(args) -> None:
    """Start the local workers' forkserver now (a local run), so that its imports of the
    drape engine overlap this process's."""
    if args.scheduler is None:
        from .pool import prepare

        prepare()


def cmd_run(args) -> int:
    _start_workers(args)
    from .workflow import run_outcome, run_report, run_study

    study = _engine_study(args)
    if study.design is not None:
        if args.method or args.chunk_size or args.no_resume:
            raise ValueError(f"{args.study} is a [design] study: --method, --chunk-size and --no-resume do not apply")
        return cmd_design(args)
    out = run_study(study, scheduler=args.scheduler, workers=args.workers, chunk_size=args.chunk_size,
                    resume=not args.no_resume, progress=args.verbosity > 0, verbose=args.verbosity > 1,
                    method=args.method)
    print(run_outcome(out))
    if not args.no_report:
        if args.verbosity > 0:
            print(f"{study.name}: writing the report (statistics, figures, HTML)", file=sys.stderr, flush=True)
        print(f"report: {run_report(out)}")
    return 0


_RUN_EPILOG = """\
examples:
  uqdrape run studies/nosecone-zero-angle.toml                 run (resuming finished chunks) and report
  uqdrape run studies/nosecone-zero-angle.toml --no-resume     draw every chunk again
  uqdrape run STUDY.toml --out results/mine --workers 2 -q     another folder, 2 processes, no progress
  uqdrape run STUDY.toml --method morris --no-report           a cheap screening run, report later
  uqdrape run STUDY.toml --scheduler tcp://host:8786           on a dask.distributed cluster
  uqdrape run STUDY.toml --out s3://bucket/runs/mine           one zarr store on S3 (AWS_* from the environment)

exit codes:
  0  done (ensemble and report written)
  2  a user error: a bad study key or flag, a folder holding another study (one line on stderr)
  3  an I/O failure: unreadable or damaged files, a full disk, an unreachable scheduler, a busy folder,
     a store that cannot be reached or written (bad URL, missing bucket, credentials, read-only or full)
  130  interrupted (Ctrl-C); run the same command again to resume
"""

_EXIT_CODES = """\
exit codes: 0 done, 2 a user error (one line on stderr naming the key, flag or path),
3 an I/O failure (unreadable or damaged files, a full disk), 130 interrupted
"""


def cmd_design(args) -> int:
    _start_workers(args)
    from .workflow import design_outcome, run_design, run_report

    study = _engine_study(args)
    out = run_design(study, scheduler=args.scheduler, workers=args.workers, progress=args.verbosity > 0)
    print(design_outcome(out))
    if not args.no_report:
        print(f"report: {run_report(out)}")
    return 0


def cmd_report(args) -> int:
    from .workflow import run_report

    print(f"report: {run_report(args.results, args.out, formats=args.format or ())}")
    return 0


def cmd_export(args) -> int:
    from .workflow import export_result

    for flag, value in (("--reference", args.reference), ("--tolerance", args.tolerance)):
        if value is not None and not math.isfinite(value):
            raise ValueError(f"{flag} must be a finite number, got {value}")
    written, notes = export_result(args.result, args.to, out=args.out, mesh=args.mesh, tolerance=args.tolerance,
                                   reference=args.reference, flavours=args.flavour, trim=args.trim, ply=args.ply,
                                   thickness=args.thickness, realizations=args.realizations, variance=args.variance)
    for note in notes:
        print(note)
    print("wrote " + ", ".join(map(str, written)))
    return 0


def cmd_calibrate(args) -> int:
    from .workflow import calibrate_drapes, calibrate_fibre_angles, check_workers

    command = "uqdrape " + shlex.join(args.argv)
    if (args.points is None) == (args.drapes is None):
        raise ValueError("give either POINTS (measured fibre angles or an image) or --drapes PART.csv ... "
                         "with --study and --parameter")
    if args.drapes is not None:
        points_only = [flag for flag, given in (("--plot", args.plot), ("--posterior", args.posterior),
                                                ("--mm-per-px", args.mm_per_px is not None)) if given]
        if points_only:
            raise ValueError(f"{', '.join(points_only)} belong(s) to a calibration from POINTS, not --drapes "
                             "(which always samples its posterior and writes its figures with --report)")
        if args.study is None:
            raise ValueError("--drapes needs --study STUDY.toml, the study whose parameters are calibrated")
        check_workers(args.workers)
        print(calibrate_drapes(args.drapes, args.study, args.parameter or [], args.out, report=args.report,
                               training_points=args.training_points, realizations=args.realizations,
                               measurement_sd=args.measurement_sd, level=args.level, scheduler=args.scheduler,
                               workers=args.workers, progress=args.verbosity > 0, command=command))
        return 0
    print(calibrate_fibre_angles(args.points, args.out, args.plot, family=args.family, criterion=args.criterion,
                                 level=args.level, fibre1_deg=args.fibre1_deg, posterior=args.posterior,
                                 mm_per_px=args.mm_per_px, window_px=args.window_px, fibre_set=args.fibre_set,
                                 report=args.report, command=command))
    return 0


def cmd_examples(args) -> int:
    """``examples``: list the shipped examples; ``examples NAME DEST``: copy one out."""
    from .workflow.examples import copy_example, list_examples

    if args.name is None:
        print(_listing(list_examples()))
        return 0
    try:
        print(f"wrote {copy_example(args.name, args.dest, overwrite=args.overwrite)}")
    except FileExistsError as err:  # the user's own file in the way: a usage error, not an I/O failure
        usage = ValueError(str(err))
        usage.names = getattr(err, "names", ())
        raise usage from None
    return 0


def cmd_serve(args) -> int:
    from .workflow import load_study, serve_study

    served = serve_study(load_study(args.study), host=args.host, port=args.port, qoi=args.qoi,
                         max_requests=args.max_requests, timeout_s=args.timeout,
                         announce=lambda line: print(line, flush=True))
    print(f"served {served} evaluations")
    return 0


def _engine_options(p: argparse.ArgumentParser) -> None:
    """The options ``run`` and ``design`` share: where the drapes run and where they go."""
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of an existing dask.distributed scheduler (default: local processes)")
    p.add_argument("--workers", type=int, help="local worker processes (default: all cores)")
    p.add_argument("--out", metavar="DIR|URL",
                   help="output folder, or an fsspec URL (s3://bucket/prefix, file:///abs/path) to write one zarr "
                        "store (default: the study's [output] directory)")
    p.add_argument("--no-report", action="store_true", help="skip the report")


def _command(sub, name: str, func, *, raw: bool = False, **kwargs) -> argparse.ArgumentParser:
    """The sub-command ``name`` run by ``func``; ``raw``: its description keeps its own line
    breaks (examples), else argparse wraps it."""
    formatter = argparse.RawDescriptionHelpFormatter if raw else argparse.HelpFormatter
    parser = sub.add_parser(name, formatter_class=formatter, **kwargs)
    parser.set_defaults(func=func)
    return parser


def build_parser() -> argparse.ArgumentParser:
    from .workflow.help_text import architectures, geometry_help

    p = argparse.ArgumentParser(
        prog="uqdrape",
        description="Uncertainty quantification of kinematic drape of dry textile preforms. "
                    "Units: mm, N, J, degrees.")
    sub = p.add_subparsers(dest="command", required=True)

    d = _command(
        sub, "drape", cmd_drape, raw=True,
        help="one deterministic drape: netCDF + pictures",
        description="Drape one pin-jointed net over a mould from a crossover point and write "
                    "OUT.nc (xarray/netCDF), OUT-net.png (the net coloured by shear) and "
                    "OUT-lines.png (shear along the max-shear lines vs distance from the crossover).\n\n"
                    "Examples:\n"
                    "  uqdrape drape --geometry hemisphere --param radius=100 --spacing 5 --rings 20\n"
                    "  uqdrape drape --mode energy --material ebxhd936_like --blankholder-force 126 \\\n"
                    "      --friction 0.2 --geometry nose_cone --spacing 5 --rings 30",
        epilog="geometry kinds and their parameters (mm, degrees):\n" + geometry_help())
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

    r = _command(sub, "run", cmd_run, help="run a study file: ensemble (netCDF chunks) + report", epilog=_RUN_EPILOG,
                 raw=True, description="Sample the study's uncertain inputs, drape every realisation in parallel "
                                       "with dask,\nstore chunks under the study's output folder (resuming finished "
                                       "chunks) and write the report.")
    r.add_argument("study", help="study file (TOML), e.g. studies/nosecone-zero-angle.toml")
    _engine_options(r)
    r.add_argument("--chunk-size", type=int, help="realisations per chunk (default: the study's)")
    r.add_argument("--method", choices=("sobol", "morris", "none"),
                   help="override the study's [sensitivity] method: 'morris' for a cheap screening run "
                        "(20 trajectories unless the study is a Morris study), 'none' for the Monte Carlo "
                        "sample; output goes to <output directory>-<method>")
    r.add_argument("--no-resume", action="store_true", help="recompute chunks that already exist")

    dsg = _command(sub, "design", cmd_design,
                   help="run a study's [design]: the blank-holder force(s) under uncertainty",
                   description="Optimise the blank-holder force (total or per sector, optionally the friction) "
                               "of a study with a [design] section: every candidate drapes the study's "
                               "realisations (common random numbers), the optimum is re-draped on a fresh "
                               "sample; writes design.nc and the report (resumes from the designs already "
                               "draped). `uqdrape run` on such a study does the same.")
    dsg.add_argument("study", help="study file (TOML) with a [design] section, e.g. studies/design-nosecone-symmetrise.toml")
    _engine_options(dsg)

    rep = _command(sub, "report", cmd_report, help="write the report of a finished run", raw=True,
                   epilog="examples:\n  uqdrape report results/nosecone-zero-angle --out results/nosecone-report\n"
                          "  uqdrape report results/nosecone-zero-angle --format svg pdf   vector figures too\n\n"
                          + _EXIT_CODES)
    rep.add_argument("results", help="a run's output folder or store URL, e.g. results/nosecone-zero-angle or "
                                     "s3://bucket/runs/nosecone")
    rep.add_argument("--out", help="report folder (default RESULTS/report; under a store's URL for a store)")
    rep.add_argument("--format", nargs="+", metavar="FORMAT",
                     help="also write every figure as FORMAT (svg, pdf: vector, text kept as text) beside its "
                          "PNG, linked from the page")

    v = _command(sub, "validate", cmd_validate, help="check study files without running them")
    v.add_argument("files", nargs="+", help="study files (TOML)")

    e = _command(
        sub, "export", cmd_export, raw=True,
        help="write a drape or an ensemble as VTK, FE-mesh orientations, a flat pattern or a cutting pattern",
        description="Export a result: a drape file (uqdrape drape --out), or a run folder or store URL\n"
                    "(uqdrape run; its per-node statistics). One file set per force level of a sweep;\n"
                    "every file of a call is written, or none.\n\n"
                    "  vtk   STEM.vtu (net: shear, status, locked or ensemble statistics, fibre directions,\n"
                    "        fibre deviation) and STEM-mould.vtu\n"
                    "  fe    STEM-fe.vtu (the mesh with per-element yarn directions and angles, shear, area\n"
                    "        ratio) and per --flavour the solver's cards of both yarns: abaqus\n"
                    "        STEM-orientations.inp (two *DISTRIBUTION + *ORIENTATION), lsdyna STEM-lsdyna.k\n"
                    "        (*ELEMENT_SHELL_BETA, two layers), nastran STEM-nastran.bdf (MCID, two layers);\n"
                    "        needs --mesh\n"
                    "  flat  STEM-flat-nodes.csv, STEM-flat-outline.csv, STEM-flat.dxf (flat blank, mm)\n"
                    "  cut   STEM-cut.dxf (layers CUT, ENVELOPE, FIBRE, SEED, LABEL) and STEM-cut.csv: the\n"
                    "        part's edge (--trim, or the mould's outline) in the flat blank, fabric axes\n"
                    "  netcdf  STEM.nc (or --out FILE.nc): the whole result as one CF netCDF file, a run's\n"
                    "        ensemble streamed chunk by chunk from its folder or store\n\n"
                    "Examples:\n"
                    "  uqdrape export results/drape/nosecone.nc --to vtk flat\n"
                    "  uqdrape export results/drape/nosecone.nc --to cut --trim edge.csv --ply P1\n"
                    "  uqdrape export results/nosecone-zero-angle --to fe --mesh part.inp --flavour abaqus lsdyna\n"
                    "  uqdrape export s3://bucket/runs/nosecone --to netcdf --out results/nosecone.nc\n"
                    "  uqdrape export results/doubledome-laminate --to fe --mesh part.inp --thickness 0.25 "
                    "--realizations 20\n\n"
                    "A laminate run (a study with [[ply]]) writes vtk, flat and cut per ply (STEM-ply-NAME...);\n"
                    "its fe is the laminate handoff: STEM-laminate.* (a composite section with each element's\n"
                    "median ply angles), STEM-rNNNN-laminate.* (one deck per realisation, --realizations of\n"
                    "them) and STEM-laminate.nc (per-element, per-ply angle samples and their KL modes).")
    e.add_argument("result", help="a drape netCDF file, a run folder or a store URL")
    e.add_argument("--to", nargs="+", required=True, choices=("vtk", "fe", "flat", "cut", "netcdf"),
                   help="what to write")
    e.add_argument("--flavour", nargs="+", choices=("abaqus", "lsdyna", "nastran"), default=["abaqus"],
                   help="the FE solvers whose cards --to fe writes (default abaqus)")
    e.add_argument("--trim", metavar="CSV",
                   help="the part's edge for --to cut: a closed polyline in plan, x_mm,y_mm a row (default: the "
                        "mould's own outline, where it has one)")
    e.add_argument("--ply", help="the ply label on the cutting pattern (default: the result's name)")
    e.add_argument("--mesh", help="surface mesh for --to fe (any format meshio reads), in mm")
    e.add_argument("--tolerance", type=float, metavar="MM",
                   help="how far an element may lie from the mould for --to fe (default: the fibre spacing)")
    e.add_argument("--reference", type=float, metavar="DEG",
                   help="plan angle of the direction fibre_deviation is measured from (default: the fabric's "
                        "orientation)")
    e.add_argument("--thickness", type=float, nargs="+", default=[1.0], metavar="MM",
                   help="a laminate's cured ply thickness for --to fe: one for all plies or one per ply (default 1)")
    e.add_argument("--realizations", type=int, default=0, metavar="N",
                   help="a laminate's Monte Carlo decks for --to fe: the first N realisations (default 0)")
    e.add_argument("--variance", type=float, default=0.99, metavar="FRACTION",
                   help="share of a laminate's angle variance its KL modes keep, in (0, 1] (default 0.99)")
    e.add_argument("--out", metavar="STEM",
                   help="output path stem, or FILE.nc for --to netcdf (default: the drape file without .nc, or "
                        "RUN/export/RUN, under a store's URL for a store)")

    srv = _command(
        sub, "serve", cmd_serve, raw=True,
        help="serve a study as a UM-Bridge model: its uncertain inputs in, chosen QoIs out",
        description="Serve STUDY over HTTP as the UM-Bridge model 'forward', so that any UQ toolkit with a\n"
                    "UM-Bridge client drives the drape. Input vector: the study's scalar factors at their\n"
                    "physical values (study order and units), then each random field's KL modes (standard\n"
                    "normals); output: one vector of the QoIs per blank-holder force level. The input\n"
                    "names, the factors' distributions and the nominal input are printed at start.\n"
                    "Listens on 127.0.0.1 (--host for others); stops on Ctrl-C, after --max-requests\n"
                    "evaluations or after --timeout seconds. Exit codes: 0 stopped, 2 a bad study or\n"
                    "argument, 3 the port is taken.\n\n"
                    "Example:\n"
                    "  uqdrape serve studies/sensitivity-vs-blankholder.toml --port 4242\n"
                    "  # then from Python (pip install umbridge), X the printed nominal input:\n"
                    "  #   umbridge.HTTPModel('http://127.0.0.1:4242', 'forward')([X])")
    srv.add_argument("study", help="study file (TOML)")
    srv.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1, this machine)")
    srv.add_argument("--port", type=int, default=4242, help="TCP port (default 4242)")
    srv.add_argument("--qoi", nargs="+", metavar="NAME",
                     help="the outputs, names of uqdrape.stats.qoi (default: the study's [sensitivity] qoi)")
    srv.add_argument("--max-requests", type=int, metavar="N", help="stop after N evaluations")
    srv.add_argument("--timeout", type=float, metavar="S", help="stop after S seconds")

    ex = _command(
        sub, "examples", cmd_examples, raw=True,
        help="list the shipped example studies and data, or copy one into a folder",
        description="List the example studies and data folders shipped with uqdrape, or copy one into DEST:\n"
                    "a study with every file it names (a mesh, measurements), a data folder whole.\n\n"
                    "Examples:\n"
                    "  uqdrape examples\n"
                    "  uqdrape examples nosecone-zero-angle studies     then: uqdrape run studies/nosecone-zero-angle.toml\n"
                    "  uqdrape examples sheartests data")
    ex.add_argument("name", nargs="?", help="the example to copy (default: list them)")
    ex.add_argument("dest", nargs="?", default=".", help="the folder to copy into (default: the current one)")
    ex.add_argument("--overwrite", action="store_true", help="replace files in DEST that differ from the example's")

    m = _command(
        sub, "materials", cmd_materials, raw=True,
        help="list material cards, show and plot one, derive one from a fabric architecture or fit one to "
             "shear tests",
        description="List the shipped material cards, show one, derive a card from a fabric "
                    "architecture (thesis ch. 4 stitch and compaction model), or fit one to picture-frame "
                    "or bias-extension test files (thesis ch. 3; the rig file's format: "
                    "uqdrape.material.sheartest.reader).\n\n"
                    "Examples:\n"
                    "  uqdrape materials\n"
                    "  uqdrape materials ebxhd936_like --plot results/cards/ebx.png\n"
                    "  uqdrape materials derive fge106hd --out results/cards/fge.toml --plot\n"
                    "  uqdrape materials derive my_fabric.toml --out cards/my_fabric.toml\n"
                    "  uqdrape materials fit pf_rig.toml --out cards/pf.toml --plot\n\n"
                    "Shipped architectures: " + ", ".join(architectures()))
    m.add_argument("name", nargs="?", help="a card name or path, or the word derive or fit")
    m.add_argument("source", nargs="?", help="derive: an architecture TOML file or a shipped architecture name; "
                                             "fit: a shear-test rig file (TOML)")
    m.add_argument("--out", metavar="CARD.toml", help="derive, fit: the card to write")
    m.add_argument("--plot", metavar="PNG", nargs="?", const=True,
                   help="write the card's N_s and W curves to this PNG; with derive, the contributions "
                        "of each term (thesis Fig 4.18), with fit the specimens, their normalised curves and "
                        "the card's band, by default next to the card")

    cal = _command(
        sub, "calibrate", cmd_calibrate, raw=True,
        help="fit a study's zero-angle field to measured fibre angles: a [uncertainty.zero_angle] block",
        description="Fit a Gaussian field (mean, sd, correlation lengths along fibre 1 and 2, a nugget for\n"
                    "measurement error) to local fibre angles measured on a flat sample, by restricted maximum\n"
                    "likelihood for each correlation family (iid, exponential, squared_exponential); keep the\n"
                    "family of least AIC (or BIC) and write it as a study block, its profile-likelihood\n"
                    "intervals in the comments. A fibre's deviation from nominal is read as the zero-energy\n"
                    "shear angle gamma0 of that set rotating against the other (uqdrape.calibration.mapping).\n\n"
                    "CSV columns: x_mm,y_mm,angle_deg,fibre_set[,sd_deg] (angle: plan direction of the fibre,\n"
                    "deg from x; fibre_set 1 or 2; sd_deg: the point's measurement sd).\n\n"
                    "With --drapes: the posterior of chosen study parameters (--parameter KEY=LOW:HIGH, a\n"
                    "uniform prior) given measured shear on formed parts (one CSV a part:\n"
                    "distance_mm,shear_deg,quadrant_sign), through a Gaussian-process emulator of the study's\n"
                    "ensemble mean and sd at the measured points over Latin-hypercube training points\n"
                    "(ensemble runs), sampled with emcee (needs uqdrape[calibrate]); writes the study at the\n"
                    "posterior medians (--out, beside the study) and the sample (-posterior.nc).\n\n"
                    "Examples:\n"
                    "  uqdrape calibrate points.csv --out results/calibration/zero_angle.toml --plot --report results/calibration/\n"
                    "  uqdrape calibrate --drapes part1.csv part2.csv --study studies/my.toml \\\n"
                    "      --parameter uncertainty.zero_angle.sd_deg=0.5:8 --out studies/my-calibrated.toml")
    cal.add_argument("points", nargs="?", help="CSV of measured fibre angles, or an image (with --mm-per-px)")
    cal.add_argument("--out", required=True, metavar="FILE.toml",
                     help="the study block to write (with --drapes: the calibrated study)")
    cal.add_argument("--plot", metavar="PNG", nargs="?", const=True,
                     help="write the calibration figure (points, fitted field, predictive check, profile "
                          "likelihoods), by default next to the block")
    cal.add_argument("--family", choices=("auto", "iid", "exponential", "squared_exponential"), default="auto",
                     help="the correlation family; auto (default): the one of least --criterion")
    cal.add_argument("--criterion", choices=("aic", "bic"), default="aic", help="how auto chooses (default aic)")
    cal.add_argument("--level", type=float, default=0.9, help="the intervals' confidence level (default 0.9)")
    cal.add_argument("--fibre1-deg", type=float, default=45.0,
                     help="nominal plan direction of fibre 1, deg from x (default 45; fibre 2 at +90)")
    cal.add_argument("--posterior", action="store_true",
                     help="also sample the parameters' posterior with emcee (pip install 'uqdrape[calibrate]'); "
                          "the block's sd_dof then comes from it")
    cal.add_argument("--mm-per-px", type=float, metavar="MM",
                     help="POINTS is an image of one fibre set's tows (.png, .jpg, .tif, .bmp): its scale, mm per "
                          "pixel; angles are read by the structure tensor (needs uqdrape[calibrate])")
    cal.add_argument("--window-px", type=float, default=8.0,
                     help="image: the structure tensor's Gaussian window sd, pixels (default 8; a sample every 2)")
    cal.add_argument("--fibre-set", type=int, choices=(1, 2), default=1, help="image: which fibre set it shows")
    cal.add_argument("--report", metavar="DIR", help="also write the calibration report, DIR/index.html")
    drapes = cal.add_argument_group("calibration from measured drapes")
    drapes.add_argument("--drapes", nargs="+", metavar="PART.csv", help="measured parts, one CSV each")
    drapes.add_argument("--study", metavar="STUDY.toml", help="the study whose parameters are calibrated")
    drapes.add_argument("--parameter", action="append", metavar="KEY=LOW:HIGH",
                        help="a study key to calibrate and its uniform prior box, repeatable "
                             "(e.g. process.friction=0.1:0.4, uncertainty.zero_angle.sd_deg=0.5:8)")
    drapes.add_argument("--training-points", type=int,
                        help="training points (ensembles) of the emulator (default 10 per parameter)")
    drapes.add_argument("--realizations", type=int, help="drapes per training point (default: the study's realizations)")
    drapes.add_argument("--measurement-sd", type=float, default=0.1,
                        help="sd of a measured shear's own error, deg (default 0.1)")
    drapes.add_argument("--scheduler", metavar="ADDRESS", help="dask.distributed scheduler (default: local processes)")
    drapes.add_argument("--workers", type=int, help="local worker processes (default: all cores)")

    p.add_argument("--version", action=_Version)
    p.set_defaults(verbosity=1)
    for parser in (p, *sub.choices.values()):  # -q / -v before or after the sub-command
        loud = parser.add_mutually_exclusive_group()
        loud.add_argument("-q", "--quiet", dest="verbosity", action="store_const", const=0, default=argparse.SUPPRESS,
                          help="no progress or information on stderr (errors still are)")
        loud.add_argument("-v", "--verbose", dest="verbosity", action="store_const", const=2,
                          default=argparse.SUPPRESS, help="more information (run: a line per finished chunk)")
    return p


class _Version(argparse.Action):
    """``--version``: the package version and, from a checkout, its git description."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, help="print the version and exit")

    def __call__(self, parser, namespace, values, option_string=None):
        from .workflow.help_text import version_text

        print(version_text())
        parser.exit()


def _os_error(err: OSError) -> str:
    """An OS error as "PATH: cause" (the cause in words, the disk-full case said plainly)."""
    cause = "the disk is full" if err.errno == errno.ENOSPC else (err.strerror or str(err))
    where = err.filename if err.filename is not None else ""
    return f"{where}: {cause}" if where else cause


def _http_refusal(err: Exception) -> OSError | None:
    """An HTTP store's answer that fsspec raises as aiohttp's ClientResponseError (e.g. 400,
    which is not an OSError) as an OSError naming the URL, else None."""
    aiohttp = sys.modules.get("aiohttp")  # not imported: the error is not aiohttp's
    if aiohttp is None or not isinstance(err, aiohttp.ClientResponseError):
        return None
    return OSError(errno.EIO, f"the store answered HTTP {err.status} {err.message}", str(err.request_info.real_url))


def _terminated(signum, frame):
    raise KeyboardInterrupt


@contextlib.contextmanager
def _no_warnings():
    """Python warnings (numpy's floating-point ones, trimesh's, meshio's, xarray's, dask's)
    kept off a command's stderr, in this process and in the worker processes it starts
    (they read PYTHONWARNINGS): what matters to the user is said in uqdrape's own one-line
    messages, and a refused value is refused before it overflows. Someone debugging who
    asks for warnings (``python -W default``, ``PYTHONWARNINGS``) gets them."""
    if sys.warnoptions:
        yield
        return
    saved = os.environ.get("PYTHONWARNINGS")
    os.environ["PYTHONWARNINGS"] = "ignore"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        if saved is None:
            os.environ.pop("PYTHONWARNINGS", None)
        else:
            os.environ["PYTHONWARNINGS"] = saved


#: Engine arguments whose option stores under another name.
_DEST = {"resume": "no_resume", "output_dir": "out", "formats": "format", "parameters": "parameter",
         "timeout_s": "timeout"}


def _flagged(parser: argparse.ArgumentParser, command: str, err: BaseException, text: str) -> str:
    """``text`` led by the flags of the arguments ``err`` names (``ParameterError.names``,
    ``errors.naming``), as ``command`` spells them."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[command]
    flags = {a.dest: max(a.option_strings, key=len) for a in sub._actions if a.option_strings}
    named = [flags[_DEST.get(n, n)] for n in getattr(err, "names", ()) if _DEST.get(n, n) in flags]
    return f"{' and '.join(named)}: {text}" if named else text


def main(argv=None) -> int:
    """Exit codes: 0 done, 2 a user error (bad study, arguments or input file), 3 an I/O or
    environment error (disk full, permissions, unreachable scheduler, a busy output folder,
    a corrupt chunk), 130 interrupted (Ctrl-C or SIGTERM). Every error is one line on stderr."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = argv  # the command line, for the history of the files it writes
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminated)  # docker stop, batch schedulers: as Ctrl-C
    try:
        with _no_warnings():
            return args.func(args)
    except (ValueError, FileNotFoundError) as err:
        text = _os_error(err) if isinstance(err, OSError) and err.errno else str(err)
        print(f"uqdrape {args.command}: error: {_flagged(parser, args.command, err, text)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`, which closed early
        sys.stderr.close()
        return 0
    except Exception as err:  # reading or writing files (a missing input is a user error above; a closed pipe
        # before), or an HTTP store's refusal
        failure = err if isinstance(err, OSError) else _http_refusal(err)
        if failure is None:
            raise
        print(f"uqdrape {args.command}: error: {_flagged(parser, args.command, err, _os_error(failure))}",
              file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print(f"uqdrape {args.command}: interrupted; finished chunks are kept, run again to resume",
              file=sys.stderr)
        return 130


def run() -> None:
    """The ``uqdrape`` command as a process (the console script, ``python -m uqdrape.cli``):
    :func:`main`, then exit with its code. What is alive then is first frozen out of the
    garbage collector (``gc.freeze``): the interpreter's last collections at exit would only
    walk it, numba's typing tables the most (0.1-0.15 s of a ``uqdrape validate``, issue 41).
    The atexit handlers run as before; ``main`` itself, called in a process that goes on
    (the tests), leaves the collector alone."""
    code = main()
    gc.freeze()
    sys.exit(code)


if __name__ == "__main__":
    run()
