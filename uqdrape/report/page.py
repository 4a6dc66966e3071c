"""The one HTML skeleton of uqdrape's report pages: the page with its inline CSS, the
provenance sentence that heads every page, and the figure grid. Pages are
self-contained (inline CSS, relative links to the PNGs beside them), so a report folder
can be copied or served as it is. The CSS widths are ``style``'s, so the page shows each
figure at the size it was drawn for; printed, the page takes an A3 landscape sheet,
wide enough for the same layout (15.7 in between 10 mm margins against the 14.25 in row)."""

from __future__ import annotations

import datetime
import html
from collections.abc import Mapping

from PIL import Image

from .._version import __version__
from ..conventions import git_version
from .style import GAP_PX, PADDING_PX, PAGE_MAX_PX, is_wide, requested_formats

_CSS = f"""
body {{ font-family: system-ui, sans-serif; max-width: {PAGE_MAX_PX}px; margin: 1.5em auto; padding: 0 {PADDING_PX}px;
  color: #222; }}
h1 {{ font-size: 1.6em; margin-bottom: 0.2em; }} h2 {{ font-size: 1.25em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }}
table {{ border-collapse: collapse; margin: 0.5em 0; }} td, th {{ border: 1px solid #ccc; padding: 0.3em 0.7em; }}
th {{ background: #f2f2f2; text-align: left; white-space: nowrap; }}
td.num {{ text-align: right; font-variant-numeric: tabular-nums; }}
.figures {{ display: grid; grid-template-columns: repeat(2, minmax(0, 1fr)); gap: {GAP_PX}px; align-items: start; }}
.wide {{ grid-column: 1 / -1; }}
figure {{ margin: 0; }} figure img {{ width: 100%; height: auto; border: 1px solid #ddd; }}
figcaption a {{ margin-left: 0.4em; }}
@media print {{ @page {{ size: A3 landscape; margin: 10mm; }} figure, tr {{ break-inside: avoid; }} }}
figcaption {{ font-size: 0.95em; color: #444; margin-top: 0.3em; }}
pre {{ background: #f7f7f7; border: 1px solid #ddd; padding: 0.8em; white-space: pre-wrap; font-size: 0.9em; }}
.note {{ color: #555; font-size: 0.95em; }}
"""


def page(title: str, body: str) -> str:
    """A whole HTML page titled ``title`` around ``body`` (HTML, already escaped)."""
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{html.escape(title)}</title>
<style>{_CSS}</style>
</head>
<body>
{body}
</body>
</html>
"""


def provenance(wall_time_s: float | None = None) -> dict:
    """Date (UTC), uqdrape version, git commit of the code (``uqdrape.conventions.git_version``,
    the ``source`` of every netCDF file; None outside a git checkout) and the run's wall
    time (s, None if not recorded)."""
    return {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "uqdrape_version": __version__, "git_commit": git_version() or None, "wall_time_s": wall_time_s}


def provenance_line(prov: Mapping) -> str:
    """The provenance as the sentence heading every report page."""
    wall = "not recorded" if prov["wall_time_s"] is None else f"{prov['wall_time_s']:.1f} s"
    return (f"Report of {prov['date']}, uqdrape {prov['uqdrape_version']}, git commit\n"
            f"{prov['git_commit'] or 'n/a (not a git checkout)'}; wall time of the run: {wall}.")


def figures_html(items) -> str:
    """The figures two to a row (a figure drawn the row's width, ``style.is_wide``, spans
    it), each linked to its vector copies if they were asked for (``style.vector_formats``),
    and the sentences standing in for figures left out, each across the row."""
    esc = html.escape
    out = []
    for item in items:
        if isinstance(item, str):
            out.append(f"<p class=\"note wide\">{esc(item)}</p>")
            continue
        path, caption = item
        with Image.open(path) as im:
            wide = " class=\"wide\"" if is_wide(im.width) else ""
        vectors = "".join(f"<a href=\"{esc(path.with_suffix('.' + fmt).name)}\">{fmt.upper()}</a>"
                          for fmt in requested_formats())
        out.append(f"<figure{wide}><a href=\"{esc(path.name)}\">"
                   f"<img src=\"{esc(path.name)}\" alt=\"{esc(caption)}\"></a><figcaption>{esc(caption)}{vectors}"
                   "</figcaption></figure>")
    return "<div class=\"figures\">\n" + "\n".join(out) + "\n</div>"
