"""Fixtures shared by the test modules."""

from __future__ import annotations

import pytest
from matplotlib.figure import Figure
from PIL import Image


@pytest.fixture()
def unrasterised(monkeypatch):
    """Report figures built in full but not rasterised: each PNG is a 1 x 1 white pixel.

    Rasterising is most of a report's time (about 1 s a figure on the 2-core machine). Tests
    of what a report holds (which figures, numbers, links, notes) use this; the pixels of
    every figure are checked by the tests that draw them
    (``test_write_report_links_and_summary_numbers`` and the figure tests of test_report).
    """
    def savefig(self, fname, *args, **kwargs):
        Image.new("RGB", (1, 1), "white").save(fname, format="png")

    monkeypatch.setattr(Figure, "savefig", savefig)
