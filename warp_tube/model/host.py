"""NumPy copies of a model's parameters and topology, for the host side.

:class:`HostArrays` is what host code reads instead of the device arrays: the frame checks, the
contact monitor, the assistant line's construction, the stability bound and the batch planner. It
holds float64 copies (float32 on the device) of the same quantities as ``TubeModel``'s arrays.

Shapes: N nodes (every curve of every tube prim, concatenated), T tubes (one per curve), P tube
prims, F forces (sorted by tube), K the most assistant lines on one tube.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["HostArrays"]


@dataclass(frozen=True)
class HostArrays:
    """A model's parameters [SI units] and topology as NumPy arrays (see module docstring)."""

    node_rest_q: np.ndarray  # (N, 3) [m] rest positions
    node_mass: np.ndarray  # (N,) [kg]
    node_inv_mass: np.ndarray  # (N,) [1/kg], 0 for pinned nodes
    node_damping: np.ndarray  # (N,) [1/s] mass-proportional damping
    seg_rest_length: np.ndarray  # (N,) [m] of the segment to the next node, 0 at a curve's last node
    seg_ke: np.ndarray  # (N,) [N/m] structural spring stiffness, 0 at a curve's last node
    seg_kd: np.ndarray  # (N,) [N s/m] structural spring damping
    node_bend_k: np.ndarray  # (N,) [N m] angular spring EI / l, 0 at the ends
    node_kappa_rest: np.ndarray  # (N, 3) [1] rest curvature binormal in the Bishop frame
    node_anchor_k: np.ndarray  # (N,) [N/m] returning spring, 0 where there is none
    node_anchor_kd: np.ndarray  # (N,) [N s/m] its damping
    node_radius: np.ndarray  # (N,) [m] tube radius at the node
    tube_node_start: np.ndarray  # (T + 1,) int, first node of each tube
    node_tube: np.ndarray  # (N,) int, tube of each node
    prim_node_start: np.ndarray  # (P,) int, first node of each tube prim
    force_order: np.ndarray  # (F,) int, scene force index of each model force
    force_tube: np.ndarray  # (F,) int
    force_node: np.ndarray  # (F,) int, global node the force pushes
    tube_force_start: np.ndarray  # (T + 1,) int, first force of each tube
    al_start: np.ndarray  # (F,) int, first assistant-line slot of each force
    force_uses_al: np.ndarray  # (F,) bool, the force builds an assistant line
    tube_al_force: np.ndarray  # (T, max(K, 1)) int, the forces with a line on each tube, -1 padded
