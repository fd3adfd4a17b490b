"""warp_tube: global deformation of tube-shaped soft bodies on NVIDIA Warp.

A deformable mass-spring centerline and a hubs-and-spokes medial surface (Huang, Gu et al.,
ISBMS 2006), with USD scenes in and time-sampled USD meshes out.
"""

from .scene import ForceSpec, Scene, SceneError, SimulationSettings, StageInfo, TubeParams, TubeSpec
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
    from .scene.usd import load_scene as _load

    return _load(path, extract=_extract_mesh)


def _extract_mesh(file, prim, info):
    """The extraction of a Mesh prim, imported (trimesh, SciPy) only when a scene has one."""
    from .extract.usd import tube_from_mesh_prim

    return tube_from_mesh_prim(file, prim, info)


def __dir__():
    return sorted(set(globals()) | set(__all__))


def __getattr__(name):
    if name == "Simulation":
        from . import io  # noqa: F401 (registers the USD writer with the frame loop)
        from .sim.simulation import Simulation

        return Simulation
    if name == "NumericalError":
        from .sim.simulation import NumericalError

        return NumericalError
    raise AttributeError(name)
