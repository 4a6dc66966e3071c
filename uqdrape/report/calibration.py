"""The calibration report: one HTML page (the shared skeleton, ``page.py``) of a
calibration's figures, its headline numbers, its warnings and the study block or study it
wrote, for ``uqdrape calibrate ... --report DIR``. The figures are drawn by
``uqdrape.report.calibration_figure``; this module only lays them out."""

from __future__ import annotations

import html
from pathlib import Path

from ..files import write_text_atomic
from .page import figures_html, page, provenance, provenance_line


def calibration_page(folder, title: str, rows, figures, written: str, warnings=(), *, seconds=None) -> Path:
    """Write ``folder/index.html``: ``rows`` (label, value) as the headline table,
    ``warnings`` as sentences above it, ``figures`` ((PNG path, caption) beside the page)
    and ``written`` (the TOML the calibration wrote, comments included). Returns the page."""
    esc = html.escape
    folder = Path(folder)
    table = "".join(f"<tr><th>{esc(label)}</th><td class=\"num\">{esc(value)}</td></tr>" for label, value in rows)
    alerts = "".join(f"<p><b>Warning:</b> {esc(w)}</p>\n" for w in warnings)
    body = (f"<h1>{esc(title)}</h1>\n<p class=\"note\">{esc(provenance_line(provenance(seconds)))}</p>\n{alerts}"
            f"<table>{table}</table>\n<h2>Figures</h2>\n{figures_html(figures)}\n"
            f"<h2>What it wrote</h2>\n<pre>{esc(written)}</pre>")
    return write_text_atomic(folder / "index.html", page(title, body))
