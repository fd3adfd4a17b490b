"""Builders shared by the benchmark problems and the tests: a clamped straight rod and a settle loop."""

from __future__ import annotations

import numpy as np


def straight_points(n_points, length, pinned_behind=True):
    """Points along +x; with ``pinned_behind`` the first segment lies behind x = 0 (a clamp)."""
    l = length / (n_points - 2 if pinned_behind else n_points - 1)
    x = (np.arange(n_points) - (1 if pinned_behind else 0)) * l
    return np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)


def settle(sim_solver, model, state, control, dt, chunk, tol, max_chunks=4000, average=10):
    """Equilibrium positions [m], shape (world, node, 3), of a damped run.

    Runs ``chunk`` substeps at a time until the largest node move per chunk is below ``tol`` [m],
    then averages the positions over ``average`` more chunks (a float32 state keeps jittering by
    ~1e-6 of its size around equilibrium).
    """
    other = model.state()
    prev = state.node_q.numpy().copy()
    for _ in range(max_chunks):
        sim_solver.integrate(state, other, control, dt, chunk)
        state, other = other, state
        q = state.node_q.numpy()
        if np.abs(q - prev).max() < tol:
            acc = np.zeros_like(q, dtype=np.float64)
            for _ in range(average):
                sim_solver.integrate(state, other, control, dt, chunk)
                state, other = other, state
                acc += state.node_q.numpy()
            return acc / average
        prev = q.copy()
    raise AssertionError("did not settle")


