"""warp_tube: global deformation of tube-shaped soft bodies on NVIDIA Warp.

A deformable mass-spring centerline and a hubs-and-spokes medial surface (Huang, Gu et al.,
ISBMS 2006), with USD scenes in and time-sampled USD meshes out.
"""

def _kernels_beside():
    """In a source checkout the kernels sit beside the package (``kernels/``, installed as
    ``warp_tube.kernels``); a checkout that shadows an installed copy of the package (Python
    started at its root, the package not installed from it in place) takes them from there."""
    import importlib.util
    import os
    import sys

    if importlib.util.find_spec(__name__ + ".kernels") is not None:
        return
    init = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "kernels", "__init__.py")
    if os.path.isfile(init):
        spec = importlib.util.spec_from_file_location(__name__ + ".kernels", init,
                                                      submodule_search_locations=[os.path.dirname(init)])  # fmt: skip
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)


_kernels_beside()

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
