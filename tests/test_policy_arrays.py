"""The integrator policy chosen for many scenes at once (``decide_integrators``, what a batch of
plain variants plans with) against the one-scene functions it repeats in array form
(``decide_integrator`` and ``substeps_for``): the same integrator, substeps and substep for every
stability bound, setting and cost, exactly (the same float64 operations)."""

import math

import numpy as np
import pytest

from warp_tube.centerline.policy import IMPLICIT_COST_RATIO, decide_integrator, decide_integrators, substeps_for
from warp_tube.scene.spec import SimulationSettings


@pytest.mark.parametrize("integrator", ["auto", "semiImplicitEuler", "implicitEuler"])
@pytest.mark.parametrize("time_step", [None, 1e-4, 2e-3, 0.1])
@pytest.mark.parametrize("cost", [IMPLICIT_COST_RATIO, 0.5, 5.0])
def test_the_policy_for_many_scenes_is_the_policy_for_each(integrator, time_step, cost):
    settings = SimulationSettings(time_step=time_step, integrator=integrator)
    frame_dt = 1.0 / 60.0
    bounds = np.concatenate([np.logspace(-7, 0, 2000), [np.inf, frame_dt, 1e-3, 2e-3]])
    decided = decide_integrators(settings, bounds, frame_dt, cost)
    assert decided is not None  # (None only where a bound's ratio to the frame is no number)
    implicit, substeps, dt = decided
    for k, hc in enumerate(bounds):
        name, step = decide_integrator(settings, float(hc), frame_dt, cost)
        n = substeps_for(frame_dt, step, settings)
        assert (bool(implicit[k]), int(substeps[k])) == (name == "implicitEuler", n), (hc, name, n)
        assert dt[k] == frame_dt / n and math.isfinite(dt[k])
