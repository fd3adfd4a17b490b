"""Stage 1, the scene: frozen dataclasses in SI units (:mod:`.spec`), USD reading and writing
(:mod:`.usd`), and the file safety every later stage writes through (:mod:`.files`)."""

from ..runtime.submodules import lazy_submodules
from .spec import ForceSpec, Scene, SceneError, SimulationSettings, StageInfo, TubeParams, TubeSpec

__all__ = ["ForceSpec", "Scene", "SceneError", "SimulationSettings", "StageInfo", "TubeParams", "TubeSpec"]

__getattr__ = lazy_submodules(__name__)  # its modules, imported on first use
