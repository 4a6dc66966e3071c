"""Fixtures shared by the test modules.

The suite caches compiled bytecode even where the environment sets
PYTHONDONTWRITEBYTECODE: without it every test process (pytest-xdist's workers included)
recompiles uqdrape and re-rewrites the test modules' asserts, 5 s of an 8 s collection on
the 2-core machine. The caches go to the ``__pycache__`` folders, beside numba's.
"""

from __future__ import annotations

import sys

import pytest
from matplotlib.figure import Figure
from PIL import Image

sys.dont_write_bytecode = False


@pytest.fixture()
def unrasterised(monkeypatch):
    """Report figures built in full but not rasterised: each PNG is a 1 x 1 white pixel.

    Rasterising is most of a report's time (about 1 s a figure on the 2-core machine). Tests
    of what a report holds (which figures, numbers, links, notes, figure sizes) use this;
    the pixels of every figure are checked by the tests that draw them
    (``test_write_report_links_and_summary_numbers`` and the figure tests of test_report).
    Returns the list of Figures "saved", in order.
    """
    saved = []

    def savefig(self, fname, *args, **kwargs):
        saved.append(self)
        Image.new("RGB", (1, 1), "white").save(fname, format="png")

    monkeypatch.setattr(Figure, "savefig", savefig)
    return saved
