"""The study-file reference, generated from the validator's own tables so that it cannot drift.

The keys of every table come from ``uqdrape.study.validate.KEYS``, the moulds and their
shape parameters from ``uqdrape.geometry.KINDS``, the scalar factors and their
distributions from ``uqdrape.study.spec``; what each key means is written once, in
``docs/user-guide/study-keys.toml``. :func:`undocumented` lists the validator's keys
without an entry (and entries without a key), which ``tests/test_docs.py`` holds empty;
as a Sphinx extension it writes ``user-guide/study-reference.md`` before the pages are read.
"""

from __future__ import annotations

import inspect
import re
import tomllib
from pathlib import Path

from uqdrape import geometry, material, schema
from uqdrape.stochastic import CORRELATIONS
from uqdrape.stochastic.sampling import STUDY_PLANS
from uqdrape.study import spec, validate

DOCS = Path(__file__).resolve().parent.parent
ENTRIES = DOCS / "user-guide" / "study-keys.toml"
PAGE = DOCS / "user-guide" / "study-reference.md"

#: Lists of valid values a description may name as ``{name}``: the validator's own.
CHOICES = {
    "qois": tuple(schema.QOI_ATTRS),
    "rare_qois": spec.RARE_QOIS,
    "target_statistics": tuple(spec.TARGET_STATISTICS),
    "materials": tuple(material.available_materials()),
    "blankholder_models": schema.BLANKHOLDER_MODELS,
    "modes": schema.MODES,
    "correlations": tuple(CORRELATIONS),
    "plans": STUDY_PLANS,
    "sensitivity_methods": spec.SENSITIVITY_METHODS,
    "sensitivity_qois": schema.SENSITIVITY_QOIS,
    "design_variables": spec.DESIGN_VARIABLES,
    "design_objectives": tuple(spec.DESIGN_OBJECTIVES),
    "design_statistics": spec.DESIGN_STATISTICS,
}


def entries() -> dict[str, dict[str, str]]:
    """The written descriptions: table name -> key -> text."""
    with open(ENTRIES, "rb") as f:
        return tomllib.load(f)


def undocumented() -> tuple[list[str], list[str]]:
    """(validator keys without a description, descriptions of keys the validator lacks), dotted."""
    written = {f"{table}.{key}" for table, keys in entries().items() for key in keys}
    valid = {f"{table}.{key}" for table, keys in validate.KEYS.items() for key in keys}
    return sorted(valid - written), sorted(written - valid)


def _code(values) -> str:
    return ", ".join(f'`"{v}"`' for v in values)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _table(name: str, written: dict[str, str]) -> list[str]:
    rows = ["| key | meaning |", "|---|---|"]
    for key in validate.KEYS[name]:
        text = re.sub(r"\{(\w+)\}", lambda m: _code(CHOICES[m[1]]) if m[1] in CHOICES else m[0], written[key])
        rows.append(f"| `{key}` | {_cell(text)} |")
    return rows + [""]


def _geometry() -> list[str]:
    rows = ["`kind` (required) chooses the mould; the other keys are that mould's shape parameters "
            "(mm, degrees), each with its default:", "", "| kind | mould | keys (default) |", "|---|---|---|"]
    for kind, cls in geometry.KINDS.items():
        params = [p for name, p in inspect.signature(cls.__init__).parameters.items() if name != "self"]
        keys = ", ".join(f"`{p.name}`" + ("" if p.default is inspect.Parameter.empty else f" ({p.default})")
                         for p in params)
        summary = (inspect.getdoc(cls) or "").split("\n")[0].replace("``", "`")
        rows.append(f"| `{kind}` | {_cell(summary)} | {keys} |")
    return rows + ["", "Every kind also takes `offset_mm` (default 0): the mould's surface that far out along "
                   "its normal (`uqdrape.geometry.Surface.offset`), where a laminate's upper plies lie.", ""]


def _factors() -> list[str]:
    rows = ["A scalar factor `[uncertainty.<factor>]` replaces a fixed setting by a distribution "
            "(values in that setting's units; the fixed value stays the nominal one). Its keys are "
            "`dist` and that distribution's parameters (`bounds = [lo, hi]`; truncnormal's mean and sd "
            "are the parent normal's, lognormal's those of the value itself):", "",
            "| factor | replaces |", "|---|---|"]
    rows += [f"| `{name}` | `{setting}` |" for name, setting in spec.FACTOR_SETTINGS.items()]
    rows += ["", "| `dist` | keys |", "|---|---|"]
    rows += [f"| `{dist}` | {', '.join(f'`{k}`' for k in spec.DIST_KEYS[dist])} |" for dist in spec.DIST_KEYS]
    rows += ["", "`card` is a score z on the card's specimen scatter: each realisation's card is "
             "N_s = mean + z·sd of the specimens (energy mode only).", ""]
    return rows


def reference() -> str:
    """The study-file reference as a MyST Markdown page."""
    written = entries()
    lines = ["# Study-file reference", "",
             "Generated from the validator's own tables (`uqdrape.study.validate.KEYS`, "
             "`uqdrape.geometry.KINDS`, `uqdrape.study.spec`): every key a study file may have, "
             "section by section, in the order they are checked. Units: mm, N, degrees. "
             "A key not listed here is refused.", ""]
    for section in spec.SECTIONS:
        lines += [f"## `[[{section}]]`" if section == "ply" else f"## `[{section}]`", ""]
        if section == "geometry":
            lines += _geometry()
        elif section == "uncertainty":
            for field in spec.FIELDS:
                lines += [f"### `[uncertainty.{field}]`", ""] + _table(f"uncertainty.{field}",
                                                                       written[f"uncertainty.{field}"])
            lines += ["### `[uncertainty.<factor>]`", ""] + _factors()
        else:
            lines += _table(section, written[section])
            for sub in (name for name in validate.KEYS if name.startswith(f"{section}.")):
                lines += [f"### `[{sub}]` (or inline: `{sub.split('.')[1]} = {{...}}`)", ""]
                lines += _table(sub, written[sub])
    return "\n".join(lines)


def write(app=None) -> Path:
    """Write the reference page (a Sphinx ``builder-inited`` handler; refuses undocumented keys)."""
    missing, stale = undocumented()
    if missing or stale:
        raise ValueError(f"{ENTRIES}: no entry for {missing}; entries of no validator key: {stale}")
    text = reference() + "\n"
    if not PAGE.exists() or PAGE.read_text(encoding="utf-8") != text:  # unchanged: no rebuild
        PAGE.write_text(text, encoding="utf-8")
    return PAGE


def setup(app):
    app.connect("builder-inited", write)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
