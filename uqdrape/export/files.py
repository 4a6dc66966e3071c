"""All-or-nothing writing of an export's files."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path


def write_all(writers: dict[Path, Callable[[Path], None]]) -> list[Path]:
    """Call each ``writer(tmp)`` to write a temporary file beside its target, then rename
    every one into place; if any writer fails, remove the temporary files and re-raise,
    so no target is written. Temporary names keep the suffix (``a.part.vtu``) because
    meshio and ezdxf pick the format from it. Returns the target paths."""
    done = []
    try:
        for target, writer in writers.items():
            target.parent.mkdir(parents=True, exist_ok=True)
            tmp = target.with_name(f"{target.stem}.part{target.suffix}")
            done.append((tmp, target))
            writer(tmp)
    except BaseException:
        for tmp, _ in done:
            tmp.unlink(missing_ok=True)
        raise
    for tmp, target in done:
        os.replace(tmp, target)
    return [target for _, target in done]
