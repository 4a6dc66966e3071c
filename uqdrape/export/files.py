"""All-or-nothing writing of an export's files: uqdrape.files.write_all (one atomic writer
for every file uqdrape writes)."""

from ..files import write_all

__all__ = ["write_all"]
