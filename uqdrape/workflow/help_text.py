"""Text the command line shows before anything heavy is imported: the mould kinds with
their parameters, the shipped architectures, the version, and what a validated study
will run."""

from __future__ import annotations

import inspect
from pathlib import Path

from ..conventions import version_text  # noqa: F401  (re-exported for the CLI)
from ..geometry import KINDS


def geometry_help() -> str:
    """One line per mould kind with its shape parameters and defaults (mm, degrees)."""
    lines = []
    for kind, cls in KINDS.items():
        sig = inspect.signature(cls.__init__)
        params = ", ".join(f"{p.name}={p.default!r}" if p.default is not p.empty else p.name
                           for p in list(sig.parameters.values())[1:])
        lines.append(f"  {kind:12s} {params}")
    return "\n".join(lines)


def architectures() -> list[str]:
    """Shipped architecture names, without importing the (numpy/scipy) material package."""
    return sorted(p.stem for p in (Path(__file__).parents[1] / "material" / "architectures").glob("*.toml"))


def describe_study(s) -> str:
    """A few lines saying what a validated study will run."""
    material = Path(s.fabric.material).name
    if s.fabric.imbalance_Nm is not None:
        material += f" with dN(30 deg) = {s.fabric.imbalance_Nm:g} N/m"
    levels_ = ", ".join(f"{f:g}" for f in s.force_levels)
    force = f"sweep {levels_} N" if s.is_sweep else f"{levels_} N"
    varying = _fields(s.uncertainty.fields) + [f"{name} ~ {factor.describe()}"
                                               for name, factor in s.uncertainty.factors.items()]
    sens = s.sensitivity.method
    if sens != "none":
        sens += f", {s.sensitivity.base_samples} base samples"
    return "\n".join([
        f"{s.name}: {s.realizations} realisations, seed {s.seed}, {s.sampling.plan} plan, chunks of {s.chunk_size}",
        f"  mould {s.geometry.build_mould().describe()}; "
        f"material {material}; spacing {s.fabric.spacing_mm:g} mm, {s.solver.rings} rings, {s.solver.mode} mode",
        f"  blank-holder force {force}, friction {s.process.friction:g}, {s.process.blankholder_model} friction model",
        f"  varying: {'; '.join(varying) if varying else 'nothing (deterministic)'}",
        f"  sensitivity: {sens}; output: {s.output_dir}"
        + (" and its fixed-parameter twin in fixed/ (twice the drapes)" if s.report.fixed_twin else ""),
        *_ply_book(s),
    ])


def _fields(fields: dict) -> list[str]:
    """One phrase per random field."""
    out = []
    for name, f in fields.items():
        what = ", ".join(f"{k} {v:g}" for k, v in f.params.items())
        length = f", L = {f.length_mm[0]:g} x {f.length_mm[1]:g} mm" if f.length_mm else ""
        drawn = "".join(f", {key} {getattr(f, key):g}" for key in ("sd_dof", "length_log_sd")
                        if getattr(f, key, None) is not None)
        out.append(f"{name} field ({what}; {f.correlation}{length}{drawn})")
    return out


def _ply_book(s) -> list[str]:
    """A laminate's plies, one line each (the study's lines then describe the rosette and
    the process every ply shares)."""
    if not s.plies:
        return []
    lines = [f"  laminate of {len(s.plies)} plies, rosette at {s.fabric.orientation_deg:g} deg, formed one by one "
             "(no inter-ply friction), each on the tool offset by the plies below it:"]
    for k, p in enumerate(s.plies):
        own = _fields(p.fields) + ([f"misalignment sd {p.misalignment_sd_deg:g} deg"] if p.misalignment_sd_deg else []) \
            + ([f"trimmed to {Path(p.trim).name}"] if p.trim else []) \
            + ([f"on the tool offset by {s.ply_offset(k):g} mm"] if s.ply_offset(k) else [])
        lines.append(f"    {p.name}: {p.angle_deg:+g} deg, {Path(p.material).name}, {p.spacing_mm:g} mm, seed point "
                     f"({p.crossover[0]:g}, {p.crossover[1]:g}) mm; {'; '.join(own) or 'no own variability'}")
    return lines
