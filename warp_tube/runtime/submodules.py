"""A package's submodules reachable as its attributes without importing them first, as
``import warp_tube; warp_tube.batch.run_batch(...)`` expects, while importing the package stays
quick (each submodule is imported on its first use)."""

from __future__ import annotations

import importlib

__all__ = ["lazy_submodules"]


def lazy_submodules(package: str, fallback=None):
    """A module ``__getattr__`` for ``package``: ``fallback(name)`` first (its own lazy names;
    None for none), then the submodule ``package.name`` imported; AttributeError where there is
    neither."""

    def __getattr__(name: str):
        if fallback is not None:
            try:
                return fallback(name)
            except AttributeError:
                pass
        if not name.startswith("__"):
            try:
                return importlib.import_module(f"{package}.{name}")
            except ModuleNotFoundError as e:
                if e.name != f"{package}.{name}":  # the submodule exists and one of its imports is missing
                    raise
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
