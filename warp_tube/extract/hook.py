"""The scene readers' hook for a Mesh prim with ``warptube:extract = true``, in a module of its
own so that reading a scene imports the extraction (trimesh, SciPy) only when it has such a prim."""

from __future__ import annotations

__all__ = ["mesh_prim_tube"]


def mesh_prim_tube(file, prim, info):
    """:func:`warp_tube.extract.usd.tube_from_mesh_prim`, imported on first use."""
    from .usd import tube_from_mesh_prim

    return tube_from_mesh_prim(file, prim, info)
