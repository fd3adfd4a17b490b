"""Batch runs: many variants of a scene (a table of overrides, the scene's USD variantSets) in one
command, as the worlds of one model, written as files, a grid stage or NumPy arrays.

``run_batch``, ``BatchResult`` and ``BatchInterrupted`` come from :mod:`warp_tube.batch.run`
(imported on first use, so the command line stays quick to start).
"""

from ..runtime.submodules import lazy_submodules

__all__ = ["run_batch", "BatchResult", "BatchInterrupted"]


def _lazy(name):
    if name in __all__:
        from . import run

        return getattr(run, name)
    raise AttributeError(name)


__getattr__ = lazy_submodules(__name__, _lazy)
