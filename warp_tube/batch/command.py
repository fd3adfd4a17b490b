"""The ``warp-tube batch`` command line: its arguments and what it prints."""

from __future__ import annotations

import os
import sys

__all__ = ["add_parser", "run", "left_behind"]


def add_parser(sub) -> None:
    """Add the ``batch`` subcommand to the ``warp-tube`` subparsers ``sub``."""
    b = sub.add_parser("batch", help="simulate many variants of a scene (a table of overrides, variantSets)",
                       description="Simulate every variant of a scene, a row of a CSV table of overrides each (and/or the "
                       "scene's variantSets), as worlds of one launch; writes the outputs and DIR/summary.csv.")
    b.add_argument("scene", help="scene .usda/.usdc")
    b.add_argument("--variants", metavar="TABLE", help="CSV: a PRIM_PATH.ATTRIBUTE column per override, a row per variant")
    b.add_argument("--variant-sets", metavar="SETS", help="cross with the scene's variantSets: all, or SET,/PRIM{SET},... (default: none)")
    b.add_argument("-o", "--output", required=True, metavar="DIR", help="batch folder (created)")
    b.add_argument("--layout", choices=("files", "grid", "arrays"), default="files",
                   help="files: DIR/variant_00000.usdc ...; grid: one stage, side by side; arrays: centerline.npy (default files)")  # fmt: skip
    b.add_argument("--every", type=int, default=1, help="write every K-th frame (default 1: every frame)")
    b.add_argument("--frames", type=int, help="frames per variant, frame 0 (rest) included (default: the scene's start to end time code)")
    b.add_argument("--no-surface", action="store_true", help="files, grid: write the Centerline only")
    b.add_argument("--surface-arrays", action="store_true", help="arrays: also write surface.npy")
    b.add_argument("--device", help="cpu or cuda:N (default: every GPU, else the CPU)")
    b.add_argument("--workers", type=int, help="CPU: N processes; CUDA: the first N GPUs (default: CPU one, or one a core "
                   "for --layout arrays with 512 rows a core or more; CUDA all)")
    b.add_argument("--writers", type=int, help="writer processes (threads for arrays; default: the cores left over, at most 8 threads for arrays, "
                   "none for a batch of USD files written in under ~0.3 s; 0: none)")
    b.add_argument("--chunk", type=int, help="variants per chunk (default 1024 on the CPU, 4096 on a GPU)")
    b.add_argument("--scheduler", metavar="ADDRESS", help="run the chunks on this Dask distributed scheduler")
    b.add_argument("--resume", action="store_true", help="go on with the unfinished batch in DIR")
    b.add_argument("--quiet", action="store_true", help="no progress (bars, or lines in a log), no summary")


def run(a) -> int:
    """Run the parsed ``batch`` command; returns the exit status."""
    from concurrent.futures.process import BrokenProcessPool

    from ..scene.spec import SceneError
    from ..runtime.interrupts import exit_status, stopped_by
    from ..runtime.progress import stderr_is_terminal
    from .progress import LINES
    from .cluster import SchedulerLost
    from .run import BatchInterrupted, run_batch

    if a.surface_arrays and a.layout != "arrays":
        raise SceneError("--surface-arrays: only with --layout arrays (files and grid write the Surface unless --no-surface)")
    if a.no_surface and a.layout == "arrays":
        raise SceneError("--no-surface: only with --layout files or grid (arrays write surface.npy with --surface-arrays)")
    surface = a.surface_arrays if a.layout == "arrays" else not a.no_surface
    # On a terminal progress bars; elsewhere (a log file) a plain line every 30 s, as run writes; none with --quiet.
    progress = False if a.quiet else (True if stderr_is_terminal() else LINES)
    try:
        result = run_batch(
            a.scene, a.output, a.variants, variant_sets=a.variant_sets, layout=a.layout, every=a.every,
            frames=a.frames, surface=surface, device=a.device, workers=a.workers, writers=a.writers, chunk=a.chunk,
            scheduler=a.scheduler, resume=a.resume, progress=progress,
        )  # fmt: skip
    except BatchInterrupted as e:
        if not a.quiet:
            print(e.result.text(), file=sys.stderr)
        print(f"warp-tube: {stopped_by(e)}; the finished variants are kept: --resume goes on", file=sys.stderr)
        return exit_status(e)
    except KeyboardInterrupt as e:  # before the batch began writing, or while it was removing its record
        print(f"warp-tube: {stopped_by(e)}; {left_behind(a.output)}", file=sys.stderr)
        return exit_status(e)
    except (SchedulerLost, BrokenProcessPool, OSError) as e:  # not bugs: what finished stays resumable
        if isinstance(e, SchedulerLost):
            why = str(e)
        elif isinstance(e, BrokenProcessPool):  # a writer or worker process killed from outside (short of memory)
            why = "a writer or worker process stopped unexpectedly (killed from outside, or out of memory?)"
        else:
            where = f"cannot write {e.filename}: " if e.filename else f"cannot write into {a.output}: "
            why = f"{where}{e.strerror or e}"
        resumable = os.path.isdir(os.path.join(a.output, ".batch"))
        more = "; the variants finished before it are kept: --resume goes on" if resumable else ""
        print(f"warp-tube: batch: {why}{more}", file=sys.stderr)
        return 2
    if not a.quiet:
        print(result.text())
    return 3 if result.failed else 0


def left_behind(out_dir: str) -> str:
    """What a batch stopped before it ran (or while it finished) left in ``out_dir``, for the one
    line it ends with: "nothing was written" alone misled where the folder holds a batch."""
    if os.path.exists(os.path.join(out_dir, ".batch", "state.json")):
        return f"{out_dir} holds an unfinished batch, its finished variants kept: --resume goes on"
    if os.path.exists(os.path.join(out_dir, ".batch-finished.json")):
        return f"{out_dir} holds a finished batch, its outputs complete: --resume goes on (and says it is finished)"
    return "nothing was written (nothing to --resume: run the batch again as it was)"
