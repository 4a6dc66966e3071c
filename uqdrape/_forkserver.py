"""Imported first by the local workers' forkserver (``uqdrape.pool.PRELOAD``): the kernel
kills it when the thread that started it dies (Linux), as it does the workers, instead of
leaving it to exit once the run's pipe closes (seconds, unloading the engine it imported)."""

from .pool import die_with_parent

die_with_parent()
