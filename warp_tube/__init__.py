"""warp_tube: global deformation of tube-shaped soft bodies on NVIDIA Warp.

A deformable mass-spring centerline and a hubs-and-spokes medial surface (Huang, Gu et al.,
ISBMS 2006), with USD scenes in and time-sampled USD meshes out.
"""

from .scene import ForceSpec, Scene, SceneError, SimulationSettings, StageInfo, TubeParams, TubeSpec
from .runtime.submodules import lazy_submodules
from .version import __version__

__all__ = [
    "ForceSpec",
    "Scene",
    "SceneError",
    "SimulationSettings",
    "StageInfo",
    "TubeParams",
    "TubeSpec",
    "load_scene",
    "Simulation",
    "NumericalError",
]


def load_scene(path):
    """Read and validate a USD scene, extracting the tubes given as meshes; see
    :func:`warp_tube.scene.usd.load_scene` and :func:`warp_tube.extract.usd.tube_from_mesh_prim`.

    Raises:
        SceneError: the first problem found, naming file, prim, attribute, found and expected.
    """
    from .extract.hook import mesh_prim_tube
    from .scene.usd import load_scene as _load

    return _load(path, extract=mesh_prim_tube)


def __dir__():
    return sorted(set(globals()) | set(__all__))


def _lazy(name):
    if name == "Simulation":
        from . import io  # noqa: F401 (registers the USD writer with the frame loop)
        from .sim.simulation import Simulation

        return Simulation
    if name == "NumericalError":
        from .sim.simulation import NumericalError

        return NumericalError
    raise AttributeError(name)


__getattr__ = lazy_submodules(__name__, _lazy)  # and the stages: warp_tube.batch, warp_tube.scene.usd, ...
