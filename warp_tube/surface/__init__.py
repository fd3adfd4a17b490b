"""Stage 3b, the surface: hubs-and-spokes rebuild orchestration (:mod:`.builder`) and the static
triangle topology (:mod:`.topology`)."""

from ..runtime.submodules import lazy_submodules

__getattr__ = lazy_submodules(__name__)  # its modules, imported on first use
