"""Every golden value says where it comes from (tests/golden.py's rule)."""

import re
from pathlib import Path

SOURCE = re.compile(r"#: (closed form: |thesis: |hand: |regression: produced by commit [0-9a-f]{7,40} \(.+\)$)")


def test_every_golden_value_has_a_provenance_line():
    lines = (Path(__file__).parent / "golden.py").read_text(encoding="utf-8").splitlines()
    names = [k for k, line in enumerate(lines) if re.match(r"[A-Z][A-Z0-9_]* = ", line)]
    assert len(names) >= 20  # the rule is applied, not skipped by a wrong pattern
    for k in names:
        assert SOURCE.match(lines[k - 1]), lines[k]
