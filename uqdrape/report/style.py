"""The one place that decides how big report figures are and how their type reads on the page.

A report page lays its figures out in a row of two columns (``page.py``'s CSS is built
from the widths here). Every figure is drawn exactly one column or one row wide, in CSS
inches (96 px each) at the reference window of :data:`WINDOW_PX` (the screenshots'), so
the page shows it at scale 1: a 10 pt label reads as 10 pt on screen, whatever the
figure. Pixels come at :data:`DPI` per displayed inch (print resolution), and every text
size is at least :data:`MIN_PT`. Vector copies (SVG, PDF) are written on request beside
the PNGs (:func:`vector_formats`), their text kept as text.
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import math

import matplotlib as mpl
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..errors import ParameterError

#: CSS pixels per inch (CSS 2.1: 1 in = 96 px).
CSS_PX_PER_IN = 96.0
#: The browser window's width (px) a page is laid out for: the README's screenshots.
WINDOW_PX = 1400
#: The page's widest body (px), its side padding (px) and the gap between two figures (px).
PAGE_MAX_PX, PADDING_PX, GAP_PX = 1500, 16, 20
#: The width (px) of a figure spanning the row and of one in a column, at ``WINDOW_PX``.
ROW_PX = min(WINDOW_PX, PAGE_MAX_PX) - 2 * PADDING_PX
COLUMN_PX = (ROW_PX - GAP_PX) / 2
#: PNG pixels per displayed inch.
DPI = 200
#: Figure widths (in): a figure is drawn this wide, so the page shows it at scale 1 (to
#: within the whole pixel they are rounded up to, 0.1 %).
ROW_IN, COLUMN_IN = (math.ceil(px / CSS_PX_PER_IN * DPI) / DPI for px in (ROW_PX, COLUMN_PX))
#: The smallest type (pt) of any text of a report figure, as the page shows it.
MIN_PT = 9.0
#: Type sizes (pt). ``NOTE_PT``: text drawn into a panel (a marked node, a note).
RC = {"font.size": 10, "axes.titlesize": 11, "axes.labelsize": 10, "legend.fontsize": 9.5,
      "legend.title_fontsize": 9.5, "xtick.labelsize": 9.5, "ytick.labelsize": 9.5, "figure.titlesize": 12,
      "svg.fonttype": "none", "pdf.fonttype": 42}
NOTE_PT = 10
#: The vector formats a report can write beside its PNGs.
VECTOR_FORMATS = ("svg", "pdf")

_vector = contextvars.ContextVar("vector_formats", default=())


def styled(func):
    """Run a figure function under the report's type sizes (a local rc context)."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with mpl.rc_context(RC):
            return func(*args, **kwargs)
    return wrapper


def figure_width(natural_in: float) -> float:
    """The width (in) a figure of ``natural_in`` is drawn at: a column if it is about a
    column wide or less (up to 20 % wider: its panels shrink a little), else the row."""
    return COLUMN_IN if natural_in <= 1.2 * COLUMN_IN else ROW_IN


def canvas(width_in: float, height_in: float, **kwargs) -> Figure:
    """A Figure on the Agg canvas, ``width_in`` x ``height_in`` scaled together to the
    width :func:`figure_width` gives (``kwargs`` to ``Figure``, e.g. ``layout``)."""
    width = figure_width(width_in)
    fig = Figure(figsize=(width, height_in * width / width_in), **kwargs)
    FigureCanvasAgg(fig)
    return fig


def is_wide(png_width_px: int) -> bool:
    """Whether a PNG of this width is a row-wide figure (else it fills a column)."""
    return png_width_px > COLUMN_IN * DPI + 1


def check_formats(formats) -> tuple[str, ...]:
    """``formats`` as a tuple, each one of :data:`VECTOR_FORMATS` (else ValueError)."""
    formats = tuple(formats or ())
    bad = [f for f in formats if f not in VECTOR_FORMATS]
    if bad:
        raise ParameterError("formats", f"{bad[0]!r} is not one of {', '.join(VECTOR_FORMATS)} (the PNGs are "
                             "always written)")
    return formats


@contextlib.contextmanager
def vector_formats(formats):
    """Within this block, every report figure is also written in each of ``formats`` (a
    subset of :data:`VECTOR_FORMATS`) beside its PNG, same stem."""
    token = _vector.set(check_formats(formats))
    try:
        yield
    finally:
        _vector.reset(token)


def requested_formats() -> tuple[str, ...]:
    """The vector formats of the enclosing :func:`vector_formats` block (none outside one)."""
    return _vector.get()
