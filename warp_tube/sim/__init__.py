"""Stage 4, the simulation: the frame loop (:mod:`.simulation`) and the contact monitor
(:mod:`.proximity`)."""

from ..runtime.submodules import lazy_submodules

__getattr__ = lazy_submodules(__name__)  # its modules, imported on first use
