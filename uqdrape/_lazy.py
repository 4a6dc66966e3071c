"""Modules imported on first use, so that light commands (``uqdrape --help``) do not load
numba, which compiling or loading the kernels needs and nothing else."""

from __future__ import annotations

import importlib.util
import sys


def lazy_module(name: str):
    """The module ``name`` (absolute), executed on its first attribute access
    (``importlib.util.LazyLoader``); the module itself if already imported."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec(name)
    spec.loader = importlib.util.LazyLoader(spec.loader)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
