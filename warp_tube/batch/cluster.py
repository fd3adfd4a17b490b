"""A batch's chunks on a Dask distributed cluster, beyond one host.

:func:`run_dask` makes each chunk a task of the cluster at ``--scheduler``: the worker simulates it
on its device and writes its outputs into the batch folder (which every worker must reach), and the
batch's process records each chunk as its task completes. Like the runs of
:mod:`warp_tube.batch.execute`, it calls ``context["finish"](chunk_id, rows, outputs)`` for each
chunk and adds its timings to the batch's result.
"""

from __future__ import annotations

import re
import time
from concurrent.futures import CancelledError

from ..scene.spec import SceneError
from .engine import simulate_chunk
from .execute import add_timings, with_rows, write_tasks
from .outputs import write

__all__ = ["run_dask", "dask_client", "check_dask", "check_scheduler_address", "SchedulerLost"]


class SchedulerLost(Exception):
    """The Dask scheduler went away (or cancelled a chunk's task) during the batch: not a bug; the
    chunks recorded before it stay, for ``--resume``."""


#: a Dask scheduler's address: PROTOCOL://HOST:PORT (the protocol may be left out: tcp), the host a
#: name, an IPv4 address or an IPv6 one in brackets
_ADDRESS = re.compile(r"^(?:(?:tcp|tls|ucx|ws|wss)://)?(?:[A-Za-z0-9_.-]+|\[[0-9A-Fa-f:.]+\]):[0-9]{1,5}$")


def _dask_task(payload):
    """A Dask task: simulate one chunk on the worker's device and write its outputs."""
    import warp as wp

    from ..sim.simulation import resolve_device

    wp.config.log_level = wp.LOG_WARNING
    scenes, choice, frames, every, surface, device, tasks = payload
    t0 = time.perf_counter()
    run = simulate_chunk(scenes, choice, resolve_device(device), frames, every, surface)
    run.ready.result()
    t1 = time.perf_counter()
    outputs = []
    for task in with_rows(tasks, run.rows, run.arrays):
        outputs += write(task)
    return run.rows, outputs, run.timings, t1 - t0, time.perf_counter() - t1


def check_dask() -> None:
    """Raise SceneError if Dask distributed is not installed (before a batch writes anything)."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise SceneError("--scheduler needs Dask distributed: pip install 'warp-tube[dask]'") from None


def check_scheduler_address(scheduler) -> None:
    """Refuse a malformed ``--scheduler`` address before anything runs (Dask's own error names
    neither the option nor the form it takes).

    Raises:
        SceneError: naming the option, the address and the form expected.
    """
    if not isinstance(scheduler, str):
        return  # (from Python: a cluster object, which Dask's Client takes)
    port = scheduler.rsplit(":", 1)[-1]
    if scheduler.startswith("inproc://") or (_ADDRESS.match(scheduler) and 0 < int(port) < 65536):
        return
    raise SceneError(f"--scheduler {scheduler!r}: expected a Dask scheduler's address, tcp://HOST:PORT (or tls://HOST:PORT)")


def dask_client(scheduler: str):
    """A client of the Dask scheduler at ``scheduler``.

    Raises:
        SceneError: Dask is not installed, or the scheduler cannot be reached.
    """
    check_dask()
    from distributed import Client

    try:
        return Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as e:
        raise SceneError(f"--scheduler {scheduler}: cannot reach the Dask scheduler ({e})") from None


def run_dask(todo, context, result) -> None:
    """Each chunk a task of the Dask cluster at ``scheduler``, simulating and writing there."""
    from distributed import as_completed

    client = dask_client(context["scheduler"])
    bar = context["bar"]
    futures = {}
    try:
        for c in todo:
            scenes = context["variants"].scenes(c.indices)
            tasks = write_tasks(c, context, 1)
            payload = (scenes, context["choices"][c.indices[0]], context["frames"], context["every"], context["surface"],
                       context["device"], tasks)  # fmt: skip
            futures[client.submit(_dask_task, payload, pure=False)] = c
        for fut in as_completed(list(futures)):
            c = futures[fut]
            try:
                rows, outputs, timings, sim_s, write_s = fut.result()
            except CancelledError as e:  # (Dask's FutureCancelledError: its reason, scheduler-connection-lost)
                why = getattr(e, "reason", "") or "cancelled"
                lost = why == "scheduler-connection-lost"
                what = "lost the connection to" if lost else f"a chunk's task was cancelled ({why}) by"
                raise SchedulerLost(f"--scheduler {context['scheduler']}: {what} the Dask scheduler") from None
            add_timings(result, timings)
            result.simulate_s += sim_s
            result.write_s += write_s
            bar.frames(len(c.indices) * max(context["frames"] - 1, 1))
            context["finish"](c.id, rows, outputs)
    except KeyboardInterrupt:
        client.cancel(list(futures))
        raise
    finally:
        client.close()
