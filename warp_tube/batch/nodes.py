"""The variants' per-node parameters, worked out once while planning and kept for the build.

Planning (:func:`warp_tube.batch.plan.run_choices`) discretises every variant to find its
stability bound: the per-node masses, stiffnesses, damping and rest shape of
:func:`~warp_tube.model.tube.node_parameters`. :class:`KeptNodes` keeps those arrays so that
building a chunk's worlds (:func:`~warp_tube.batch.worlds.build_worlds`) takes its variants' rows
instead of discretising them a second time: the same function of the same tubes, so the same
numbers. They are kept up to :data:`KEEP_NODES` nodes in all (a larger batch discretises each
chunk again), and only where the planning ran in the simulating process.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .worlds import WorldArrays

__all__ = ["KeptNodes", "KEEP_NODES"]

#: nodes of a batch whose per-node parameters are kept (~130 bytes a node: ~0.5 GB)
KEEP_NODES = 1 << 22


class KeptNodes:
    """Per-node parameters of a batch's variants (by batch index), as planning made them.

    Args:
        count: the batch's variants.
        limit: nodes kept at most (default :data:`KEEP_NODES`).

    Attributes:
        fields: the fields kept: :class:`~warp_tube.batch.worlds.WorldArrays`' (what a build takes).
    """

    def __init__(self, count: int, limit: int | None = None):
        self.fields = tuple(f.name for f in dataclasses.fields(WorldArrays))
        self.limit = KEEP_NODES if limit is None else limit
        self.nodes = 0
        self.block = np.full(count, -1, dtype=np.int64)  # per variant its block, -1 if not kept
        self.row = np.zeros(count, dtype=np.int64)  # and its row in the block
        self.blocks: list[tuple[int, dict]] = []  # (nodes per variant, {field: (variants, N, ...)})

    def add(self, indices, per_node: dict) -> None:
        """Keep ``per_node`` (:func:`~warp_tube.model.tube.node_parameters` of the variants
        ``indices``' tubes, one after another, each with as many nodes) unless over the limit."""
        count = len(indices)
        n = len(per_node["node_mass"])
        if not count or n % count or self.nodes + n > self.limit:
            return
        N = n // count
        self.blocks.append((N, {f: per_node[f].reshape((count, N) + per_node[f].shape[1:]) for f in self.fields}))
        self.block[np.asarray(indices, dtype=np.int64)] = len(self.blocks) - 1
        self.row[np.asarray(indices, dtype=np.int64)] = np.arange(count)
        self.nodes += n

    def same_as(self, index: int, other: int) -> None:
        """Variant ``index`` has variant ``other``'s parameters (an equal scene)."""
        self.block[index], self.row[index] = self.block[other], self.row[other]

    def take(self, indices) -> dict | None:
        """The kept fields of the variants ``indices`` (W of them), each (W, N, ...), or None
        where any was not kept or they differ in their nodes."""
        idx = np.asarray(indices, dtype=np.int64)
        blocks = self.block[idx]
        if not len(idx) or blocks[0] < 0 or not np.all(blocks == blocks[0]):
            return None
        _, arrays = self.blocks[int(blocks[0])]
        rows = self.row[idx]
        if np.all(np.diff(rows) == 1):  # a run of rows: views
            a, b = int(rows[0]), int(rows[-1]) + 1
            return {f: v[a:b] for f, v in arrays.items()}
        return {f: v[rows] for f, v in arrays.items()}
