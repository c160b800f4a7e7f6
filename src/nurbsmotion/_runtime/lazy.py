"""Names a package loads on first use (PEP 562), for the package façade and ``study``."""

from __future__ import annotations

import sys
from importlib import import_module


def lazy_names(package: str, table: dict[str, str]):
    """``(__getattr__, __dir__)`` for the package ``package`` whose public names ``table``
    maps to the submodule (relative to the package) that holds each one."""

    def __getattr__(name):
        if name in table:
            return getattr(import_module(f".{table[name]}", package), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        module = sys.modules[package]
        return sorted(set(vars(module)) | set(module.__all__))

    return __getattr__, __dir__
