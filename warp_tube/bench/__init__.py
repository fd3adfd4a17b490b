"""Benchmarks users can run: analytic references (:mod:`.references`)."""

from ..runtime.submodules import lazy_submodules

__getattr__ = lazy_submodules(__name__)  # its modules, imported on first use
