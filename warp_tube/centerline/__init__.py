"""Stage 3a, the centerline: semi-implicit Euler (:mod:`.explicit`), implicit Euler (:mod:`.implicit`)
and the stability bound (:mod:`.stability`)."""

from ..runtime.submodules import lazy_submodules

__getattr__ = lazy_submodules(__name__)  # its modules, imported on first use
