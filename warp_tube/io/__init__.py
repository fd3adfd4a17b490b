"""Stage 5, output: the USD writer (:mod:`.writer`), OBJ/glTF export (:mod:`.export`), PNG previews
(:mod:`.preview`). Importing it registers the USD writer with the
frame loop (:mod:`warp_tube.sim.output`)."""

from ..runtime.submodules import lazy_submodules
from ..sim.output import register_writer
from ..scene.files import USD_EXTENSIONS
from .writer import StageWriter

register_writer(USD_EXTENSIONS, StageWriter)

__getattr__ = lazy_submodules(__name__)  # its modules, imported on first use
