"""Stage 2, the model: TubeModel/State/Control built from a Scene (:mod:`.tube`) and the NumPy
frame toolkit of rest geometry (:mod:`.frames`)."""

from ..runtime.submodules import lazy_submodules

__getattr__ = lazy_submodules(__name__)  # its modules, imported on first use
