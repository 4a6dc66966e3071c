"""Modules imported on first use, so that light commands (``uqdrape --help``) do not load
numba, which compiling or loading the kernels needs and nothing else; and a package's
names imported on first use (PEP 562: :func:`lazy_exports`)."""

from __future__ import annotations

import importlib
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


def lazy_exports(package: str, exports: dict):
    """``(__getattr__, __dir__)`` for the package ``package`` (its ``__name__``) whose names
    are imported from its modules on first use: ``exports`` maps a module relative to the
    package (``".run"``, ``"..pool"``) to the names it holds (a name listed twice: the
    later module's)."""
    home = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str):
        if name not in home:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(home[name], package), name)

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *home})

    return __getattr__, __dir__
