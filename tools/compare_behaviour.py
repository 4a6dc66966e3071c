"""Behaviour before and after a change: the same small runs at two commits, compared.

Run: python tools/compare_behaviour.py [OLD [NEW]] [--keep DIR] [--workers N]
(defaults: 70dbbb6, where issue 35 started, and HEAD; about 5 minutes on 2 cores).

Each commit is checked out into a temporary git worktree and run with its own code
(``PYTHONPATH=<worktree>``, this interpreter's packages; the import is checked to come
from the worktree). Both run the same fixed set: four shipped studies made small (fewer
realisations, rings or base samples; the same edit at both commits, written beside the
shipped file so relative paths hold), one energy drape file, exports of a run and of the
drape file (netCDF, VTK, FE cards of three solvers, flat and cutting patterns) and the
material cards command (a derived card, a shown one). Then, file by file:

- ensemble chunks and every netCDF file: each variable's values bitwise (dtype, shape,
  NaNs in the same places), the variable and attribute names; the attributes that record
  when, where and by which checkout a file was made (history, date_created, source) are
  not compared;
- the report's summary.json: every number and string, paths of the two trees made equal;
- every other file a command wrote (VTK, cards, CSV, DXF, TOML, JSON): bytes, else text
  with dates, versions, paths and DXF handles normalised; figures (PNG, HTML) are not
  compared;
- the files each command wrote: names on one side only.

Differences the change meant are named with their reason (:data:`INTENDED`); the table
marks every other one as a finding. Exit 0 when nothing unexplained differs, else 1.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: (study file, {(table, key): value}): four shipped studies, small; one a mesh mould, one a
#: force sweep with a Sobol' sample.
STUDIES = {
    "plate-spacing.toml": {("study", "realizations"): 16, ("study", "chunk_size"): 8, ("solver", "rings"): 10,
                           ("report", "histogram_nodes"): "[[2, 2], [5, 5], [8, 8]]"},
    "nosecone-zero-angle.toml": {("study", "realizations"): 16, ("study", "chunk_size"): 8, ("solver", "rings"): 12},
    "cspar-misalignment.toml": {("study", "realizations"): 8, ("study", "chunk_size"): 4, ("solver", "rings"): 10},
    "sensitivity-vs-blankholder.toml": {("sensitivity", "base_samples"): 64, ("solver", "rings"): 8},
}
#: The other commands, after the runs: (label, argv); {OUT} is the output folder, {TREE} the checkout.
COMMANDS = [
    ("drape", ["drape", "--geometry", "nose_cone", "--spacing", "5", "--rings", "30", "--mode", "energy",
               "--material", "ebxhd936_like", "--blankholder-force", "100", "--out", "{OUT}/drape/nosecone"]),
    ("export drape", ["export", "{OUT}/drape/nosecone.nc", "--to", "netcdf", "vtk", "flat", "cut",
                      "--trim", "{TREE}/studies/meshes/nosecone-ply-edge.csv", "--out", "{OUT}/export-drape/nosecone"]),
    ("export run", ["export", "{OUT}/run/nosecone-zero-angle", "--to", "netcdf", "vtk", "fe",
                    "--mesh", "{TREE}/studies/meshes/nosecone-part.inp", "--flavour", "abaqus", "lsdyna", "nastran",
                    "--out", "{OUT}/export-run/nosecone"]),
    ("export mesh run", ["export", "{OUT}/run/cspar-misalignment", "--to", "vtk", "fe",
                         "--mesh", "{TREE}/studies/meshes/cspar.stl", "--out", "{OUT}/export-mesh/cspar"]),
    ("material card", ["materials", "derive", "fge106hd", "--out", "{OUT}/cards/fge106hd.toml"]),
    ("material show", ["materials", "ebxhd936_like"]),
]
#: Differences the change meant: (what differs, a regular expression on the row's item and
#: detail, why).
INTENDED = [
    ("sample, not design", r"attr.*\b(design|sample)_(method|base_samples|evaluations)\b|"
     r"kind: sensitivity design vs sensitivity sample|output_constant\.long_name: .*design.* vs .*sample",
     "issue 35: a SALib sample matrix is no design; design_* attributes renamed sample_* "
     "(conventions.RENAMED_ATTRS reads both), the study kind 'sensitivity design' is 'sensitivity sample'"),
    ("applied force of a drape file", r"nosecone\.nc.* variables blankholder_force only in old; "
     r"applied_blankholder_force only in new",
     "issue 35: a drape file keeps the force its drape saw as applied_blankholder_force, as an ensemble does "
     "(conventions.RENAMED_VARIABLES reads the old name)"),
    ("checksum files", r"\.sha256\b|checksum",
     "issue 40: a SHA-256 checksum beside each chunk (and the run's checksum_key in run.json), checked by every "
     "reader"),
    ("card description", r"cards/show\.txt .*picture-frame scale' vs .*an assumed shape",
     "issue 38 (9ab2b18): the *_like cards' descriptions say they are assumed shapes, not measured"),
]
VOLATILE_ATTRS = {"history", "date_created", "source"}
SKIP_SUFFIXES = {".png", ".html", ".lock"}


def tree(commit: str, where: Path) -> Path:
    """A detached worktree of ``commit`` in a new folder under ``where``."""
    where.mkdir(parents=True, exist_ok=True)
    path = Path(tempfile.mkdtemp(prefix=f"{commit}-", dir=where))
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(path), commit], check=True)
    return path


def override(text: str, values: dict) -> str:
    """The TOML ``text`` with each (table, key) of ``values`` set: replaced in its table,
    else added under the table's header."""
    lines, table, done = text.splitlines(), None, set()
    for n, line in enumerate(lines):
        header = re.match(r"\s*\[([^\]]+)\]", line)
        table = header.group(1).strip() if header else table
        key = re.match(r"\s*([A-Za-z0-9_]+)\s*=", line)
        if key and (table, key.group(1)) in values:
            lines[n] = f"{key.group(1)} = {values[(table, key.group(1))]}"
            done.add((table, key.group(1)))
    for t, k in set(values) - done:
        at = next((n for n, line in enumerate(lines) if line.strip() == f"[{t}]"), None)
        if at is None:
            raise ValueError(f"table [{t}] is not in the study")
        lines.insert(at + 1, f"{k} = {values[(t, k)]}")
    return "\n".join(lines) + "\n"


def uqdrape(checkout: Path, argv: list[str], log: Path, stdout: Path | None = None) -> int:
    """Run the CLI of ``checkout`` with ``argv``; its output into ``log`` (stdout into
    ``stdout`` where given)."""
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    code = "import sys; from uqdrape.cli import main; sys.exit(main(sys.argv[1:]))"
    with open(log, "a", encoding="utf-8") as f, open(stdout or os.devnull, "w", encoding="utf-8") as o:
        f.write(f"$ uqdrape {' '.join(argv)}\n")
        f.flush()
        return subprocess.run([sys.executable, "-c", code, *argv], cwd=checkout, env=env,
                              stdout=o if stdout else f, stderr=f).returncode


def run_all(checkout: Path, out: Path, workers: int) -> dict:
    """Every study and command at ``checkout``, into ``out``: {label: exit code}."""
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    where = subprocess.run([sys.executable, "-c", "import uqdrape; print(uqdrape.__file__)"], env=env, cwd=out,
                           capture_output=True, text=True, check=True).stdout.strip()
    if not Path(where).resolve().is_relative_to(checkout.resolve()):
        raise SystemExit(f"uqdrape imports from {where}, not from {checkout}")
    log = out / "log.txt"
    codes = {}
    for name, values in STUDIES.items():
        study = checkout / "studies" / f"_compare-{name}"
        study.write_text(override((checkout / "studies" / name).read_text(encoding="utf-8"), values), encoding="utf-8")
        codes[f"run {name}"] = uqdrape(checkout, ["run", str(study), "--out", str(out / "run" / Path(name).stem),
                                                  "--workers", str(workers), "-q"], log)
    for label, argv in COMMANDS:
        argv = [a.replace("{OUT}", str(out)).replace("{TREE}", str(checkout)) for a in argv]
        codes[label] = uqdrape(checkout, argv, log, out / "cards" / "show.txt" if label == "material show" else None)
    return codes


# -- comparison ---------------------------------------------------------------------------------

def _normal_text(text: str, roots: tuple[str, ...]) -> str:
    for root in roots:
        text = text.replace(root, "<ROOT>")
    text = re.sub(r"\d{4}-\d\d-\d\d[T ]\d\d:\d\d:\d\d(\.\d+)?(Z|[+-]\d\d:\d\d)?", "<TIME>", text)
    text = re.sub(r"\d{4}-\d\d-\d\d", "<DATE>", text)
    text = re.sub(r"\(git [^)]*\)", "(git <REV>)", text)
    text = re.sub(r"\b\d+\.\d+ s\b", "<SECONDS> s", text)
    return text


def _dxf_text(path: Path) -> str:
    """A DXF file's group pairs without the header's times and GUIDs."""
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    pairs = list(zip(lines[::2], lines[1::2]))
    out, skip = [], False
    for code, value in pairs:
        if code.strip() == "9":
            skip = value.strip() in ("$TDCREATE", "$TDUCREATE", "$TDUPDATE", "$TDUUPDATE", "$TDINDWG", "$TDUSRTIMER",
                                     "$FINGERPRINTGUID", "$VERSIONGUID")
            out.append(value)
        elif not skip:
            out.append(f"{code.strip()} {value}")
    return "\n".join(out)


def _netcdf_rows(rel: str, a: Path, b: Path, roots) -> list[tuple[str, str]]:
    """(item, detail) of every difference between two netCDF files, read without decoding;
    text attributes with the paths of ``roots`` made equal."""
    import xarray as xr

    rows = []
    with xr.open_dataset(a, decode_cf=False, decode_times=False) as x, \
            xr.open_dataset(b, decode_cf=False, decode_times=False) as y:
        rows += _only(rel, "variables", set(x.variables), set(y.variables))
        for name in sorted(set(x.variables) & set(y.variables)):
            u, v = x[name].values, y[name].values
            if u.dtype != v.dtype or u.shape != v.shape:
                rows.append((rel, f"variable {name}: {u.dtype}{u.shape} vs {v.dtype}{v.shape}"))
            elif not np.array_equal(u, v, equal_nan=u.dtype.kind in "fc"):
                n = int(np.sum(~((u == v) | (np.isnan(u) & np.isnan(v)) if u.dtype.kind in "fc" else (u == v))))
                rows.append((rel, f"variable {name}: {n} of {u.size} values differ"))
            attrs = {k for k in set(x[name].attrs) | set(y[name].attrs)
                     if str(x[name].attrs.get(k)) != str(y[name].attrs.get(k))}
            rows += [(rel, f"attr {name}.{k}: {str(x[name].attrs.get(k))[:40]!r} vs {str(y[name].attrs.get(k))[:40]!r}")
                     for k in sorted(attrs)]
        rows += _only(rel, "global attrs", set(x.attrs), set(y.attrs))
        rows += [(rel, f"global attr {k}") for k in sorted(set(x.attrs) & set(y.attrs) - VOLATILE_ATTRS)
                 if _normal_text(str(x.attrs[k]), roots) != _normal_text(str(y.attrs[k]), roots)]
    return rows


def _only(rel: str, what: str, old: set, new: set) -> list[tuple[str, str]]:
    """One row naming the ``what`` only in ``old`` and only in ``new`` (none if there are none)."""
    sides = [f"{', '.join(sorted(names))} only in {side}" for names, side in ((old - new, "old"), (new - old, "new"))
             if names]
    return [(rel, f"{what} {'; '.join(sides)}")] if sides else []


def _json_leaves(value, path=""):
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _json_leaves(v, f"{path}.{k}" if path else k)
    elif isinstance(value, list) and value and all(isinstance(v, (dict, list)) for v in value):
        for i, v in enumerate(value):
            yield from _json_leaves(v, f"{path}[{i}]")
    else:
        yield path, value


def _json_rows(rel: str, a: Path, b: Path, roots) -> list[tuple[str, str]]:
    x, y = (dict(_json_leaves(json.loads(_normal_text(p.read_text(encoding="utf-8"), roots)))) for p in (a, b))
    volatile = {k for k in {*x, *y} if re.search(r"second|time|date|elapsed|version|host|cpu|load|git", k, re.I)}
    rows = _only(rel, "keys", set(x) - volatile, set(y) - volatile)
    return rows + [(rel, f"key {key}: {str(x[key])[:60]} vs {str(y[key])[:60]}")
                   for key in sorted(set(x) & set(y) - volatile) if x[key] != y[key]]


def compare(old: Path, new: Path, roots_old, roots_new) -> tuple[list, int]:
    """Rows (item, result, detail) for every file under ``old`` and ``new``; and the count of files compared."""
    files_old = {p.relative_to(old).as_posix() for p in old.rglob("*") if p.is_file()}
    files_new = {p.relative_to(new).as_posix() for p in new.rglob("*") if p.is_file()}
    rows, count = [], 0
    for rel in sorted(files_old ^ files_new):
        if Path(rel).suffix not in SKIP_SUFFIXES and rel != "log.txt":
            rows.append((rel, f"file only in {'old' if rel in files_old else 'new'}"))
    for rel in sorted(files_old & files_new):
        a, b = old / rel, new / rel
        suffix = a.suffix.lower()
        if suffix in SKIP_SUFFIXES or rel == "log.txt":
            continue
        count += 1
        if a.read_bytes() == b.read_bytes():
            continue
        if suffix == ".nc":
            rows += _netcdf_rows(rel, a, b, (*roots_old, *roots_new))
        elif suffix == ".json":
            rows += _json_rows(rel, a, b, (*roots_old, *roots_new))
        else:
            read = _dxf_text if suffix == ".dxf" else lambda p: p.read_text(encoding="utf-8", errors="replace")
            ta, tb = _normal_text(read(a), roots_old), _normal_text(read(b), roots_new)
            if ta != tb:
                la, lb = ta.splitlines(), tb.splitlines()
                first = next((i for i, (p, q) in enumerate(zip(la, lb)) if p != q), min(len(la), len(lb)))
                p, q = (la[first:first + 1] or [""])[0], (lb[first:first + 1] or [""])[0]
                col = max(next((k for k, (u, v) in enumerate(zip(p, q)) if u != v), min(len(p), len(q))) - 10, 0)
                rows.append((rel, f"text differs from line {first + 1}: ...{p[col:col + 40]!r} vs ...{q[col:col + 40]!r}"))
    return rows, count


def grouped(rows) -> list[tuple[str, str]]:
    """``rows`` with the same detail for several files of the same depth and suffix as one
    row, the path parts that differ as ``*`` (``run/*/run.json (4 files)``)."""
    groups: dict[tuple, list[Path]] = {}
    for item, detail in rows:
        path = Path(item)
        groups.setdefault((detail, len(path.parts), "".join(path.suffixes)), []).append(path)
    out = []
    for (detail, _, suffix), paths in groups.items():
        if len(paths) == 1:
            out.append((paths[0].as_posix(), detail))
            continue
        parts = ["*" if len({p.parts[k] for p in paths}) > 1 else paths[0].parts[k] for k in range(len(paths[0].parts))]
        parts[-1] = parts[-1] + suffix if parts[-1] == "*" else parts[-1]
        out.append((f"{'/'.join(parts)} ({len(paths)} files)", detail))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", nargs="?", default="70dbbb6")
    parser.add_argument("new", nargs="?", default="HEAD")
    parser.add_argument("--keep", type=Path, help="write the outputs into this folder and keep them")
    parser.add_argument("--workers", type=int, default=1, help="worker processes of each run (default 1)")
    args = parser.parse_args(argv)
    commits = [subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", c], capture_output=True, text=True,
                              check=True).stdout.strip() for c in (args.old, args.new)]
    base = args.keep or Path(tempfile.mkdtemp(prefix="compare-behaviour-"))
    base.mkdir(parents=True, exist_ok=True)
    trees, outs, codes = [], [], []
    try:
        for commit in commits:
            checkout = tree(commit, base / "trees")
            out = base / "out" / commit
            (out / "cards").mkdir(parents=True, exist_ok=True)
            print(f"running {commit} in {checkout} ...", file=sys.stderr, flush=True)
            trees.append(checkout)
            outs.append(out)
            codes.append(run_all(checkout, out, args.workers))
        rows, count = compare(outs[0], outs[1], (str(outs[0]), str(trees[0])), (str(outs[1]), str(trees[1])))
    finally:
        for checkout in trees:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(checkout)], check=False)
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)
    table = [(label, f"exit {codes[0][label]} / {codes[1][label]}", "same" if codes[0][label] == codes[1][label]
              else "FINDING") for label in codes[0]]
    findings = sum(1 for row in table if row[2] == "FINDING")
    reasons = set()
    for item, detail in grouped(rows):
        reason = next((f"{what}: {why}" for what, pattern, why in INTENDED if re.search(pattern, f"{item} {detail}")),
                      None)
        table.append((item, detail, "intended" if reason else "FINDING"))
        reasons.add(reason)
        findings += reason is None
    width = max(len(r[0]) for r in table)
    print(f"behaviour of {commits[0]} (old) against {commits[1]} (new): {count} files compared in both")
    print(f"{'item':{width}}  {'result':11}  detail")
    for item, detail, verdict in table:
        print(f"{item:{width}}  {verdict:11}  {detail}")
    if reasons - {None}:
        print("\nintended differences:")
        print("\n".join(f"- {reason}" for reason in sorted(reasons - {None})))
    print(f"\n{findings} unexplained difference(s)" + ("" if args.keep is None else f"; outputs under {base}"))
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
