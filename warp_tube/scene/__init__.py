"""Stage 1, the scene: frozen dataclasses in SI units (:mod:`.spec`) and USD reading and writing
(:mod:`.usd`)."""

from .spec import ForceSpec, Scene, SceneError, SimulationSettings, StageInfo, TubeParams, TubeSpec

__all__ = ["ForceSpec", "Scene", "SceneError", "SimulationSettings", "StageInfo", "TubeParams", "TubeSpec"]
