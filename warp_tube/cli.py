"""Command line: ``warp-tube run | check | extract | preview | export | bench``.

Exit status: 0 done; 2 invalid input or request (message, no traceback, nothing simulated, no
output file); 3 numerical failure (the frames finished so far are kept); 130 interrupted.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from importlib import resources

from .scene.spec import SceneError

EXIT_OK, EXIT_INPUT, EXIT_NUMERICAL, EXIT_INTERRUPTED = 0, 2, 3, 130


def default_scene_path() -> str:
    """Path of the embedded default scene (a clamped tube bent by a time-varying push)."""
    return str(resources.files("warp_tube") / "data" / "default.usda")


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.print_usage(sys.stderr)
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        sys.exit(EXIT_INPUT)


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="warp-tube", description="Simulate tube-shaped soft bodies: USD scene in, time-sampled USD out.")
    p.add_argument("-v", "--verbose", action="store_true", help="log details")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    r = sub.add_parser("run", help="simulate a scene and write a time-sampled USD stage")
    r.add_argument("scene", nargs="?", help="scene .usda/.usdc (default: the embedded default scene)")
    r.add_argument("-o", "--output", help="output stage (.usdc, .usda); default: the scene's name + .usdc here")
    r.add_argument("--device", help="cpu or cuda:N (default: CUDA when available)")
    r.add_argument("--frames", type=int, help="frames to write, frame 0 (rest) included")
    r.add_argument("--every", type=int, default=1, help="write every K-th frame")
    r.add_argument("--no-surface", action="store_true", help="write the Centerline only")
    r.add_argument("--quiet", action="store_true", help="no progress bar, no summary")

    c = sub.add_parser("check", help="validate a scene without simulating")
    c.add_argument("scene")

    e = sub.add_parser("extract", help="extract a tube scene from a surface mesh (STL, PLY, OBJ)")
    e.add_argument("mesh")
    e.add_argument("-o", "--output", required=True, help="scene .usda to write")
    e.add_argument("--hubs", type=int, help="centerline points (default: from length and radius)")
    e.add_argument("--spokes", type=int, default=16, help="spokes per hub")
    e.add_argument("--scale", type=float, nargs="+", metavar="F", help="F, or FX FY FZ: mesh units to metres")

    v = sub.add_parser("preview", help="render a contact sheet of an output stage to PNG")
    v.add_argument("stage")
    v.add_argument("-o", "--output", required=True, help="PNG to write")
    v.add_argument("--frames", type=int, default=4, help="frames on the sheet")

    x = sub.add_parser("export", help="export an output stage's Surface as OBJ or glTF binary")
    x.add_argument("stage")
    x.add_argument("--format", choices=("obj", "glb"), default="obj")
    x.add_argument("-o", "--output", help="output file or folder (default: beside the stage)")
    x.add_argument("--frame", type=float, help="only this time code")

    b = sub.add_parser("bench", help="speed against error beside peer simulators; results, report and plots")
    b.add_argument("-o", "--output", required=True, help="folder for results.json, report.md and the plots")
    b.add_argument("--suite", choices=("accuracy", "speed", "all"), default="all")
    b.add_argument("--peers", help="pyelastica,newton (default: both where installed) or none")
    b.add_argument("--device", help="cpu or cuda:N (default: CUDA when available)")
    b.add_argument("--quick", action="store_true", help="the small problem set (tests, a first look)")
    b.add_argument("--repeat", type=int, help="interleaved repetitions (default 3; 1 with --quick)")
    b.add_argument("--replot", metavar="RESULTS", help="only rewrite report and plots from an earlier results.json")
    return p


def _cmd_run(a) -> int:
    from .sim.simulation import NumericalError, Simulation
    from . import load_scene
    from .io.writer import check_output_path

    scene_path = a.scene or default_scene_path()
    out = a.output or os.path.splitext(os.path.basename(a.scene or "tube"))[0] + ".usdc"
    out = check_output_path(out)
    if a.frames is not None and a.frames < 1:
        raise SceneError(f"--frames {a.frames}: expected at least 1")
    if a.every < 1:
        raise SceneError(f"--every {a.every}: expected at least 1")
    scene = load_scene(scene_path)
    sim = Simulation(scene, device=a.device, surface=not a.no_surface)
    tty = sys.stderr.isatty() and not a.quiet
    try:
        summary = sim.run(frames=a.frames, output=out, progress=tty, every=a.every)
    except NumericalError as e:
        print(sim.last_summary.text(), file=sys.stderr)
        print(f"warp-tube: {e}", file=sys.stderr)
        return EXIT_NUMERICAL
    except KeyboardInterrupt:
        print(sim.last_summary.text(), file=sys.stderr)
        print("warp-tube: interrupted; the frames finished so far are in the output", file=sys.stderr)
        return EXIT_INTERRUPTED
    if not a.quiet:
        print(summary.text())
    return EXIT_OK


def _cmd_check(a) -> int:
    from . import load_scene

    s = load_scene(a.scene)
    n = sum(len(t.curve_counts) for t in s.tubes)
    print(f"{a.scene}: valid: {n} tube(s) in {len(s.tubes)} prim(s), {len(s.forces)} force(s), "
          f"{s.stage.frame_count} frames at {s.stage.time_codes_per_second:g} per second")  # fmt: skip
    return EXIT_OK


def _cmd_extract(a) -> int:
    from .extract.command import extract_to_scene

    if a.scale is not None and len(a.scale) not in (1, 3):
        raise SceneError(f"--scale takes 1 or 3 values, got {len(a.scale)}")
    extract_to_scene(a.mesh, a.output, hubs=a.hubs, spokes=a.spokes, scale=a.scale)
    return EXIT_OK


def _cmd_preview(a) -> int:
    from .io.preview import preview

    preview(a.stage, a.output, frames=a.frames)
    print(a.output)
    return EXIT_OK


def _cmd_export(a) -> int:
    from .io.export import export

    for path in export(a.stage, fmt=a.format, out=a.output, frame=a.frame) or []:
        print(path)
    return EXIT_OK


def _cmd_bench(a) -> int:
    from .bench.command import parse_peers, replot, run_bench

    if a.replot:
        replot(a.replot, a.output)
        return EXIT_OK
    repeat = a.repeat if a.repeat is not None else (1 if a.quick else 3)
    if repeat < 1:
        raise SceneError(f"--repeat {repeat}: expected at least 1")
    peers = parse_peers(a.peers)
    command = "warp-tube bench " + " ".join(a.argv)
    run_bench(a.suite, peers, a.device, a.output, repeat, a.quick, log=lambda m: print(m, file=sys.stderr), command=command)
    print(os.path.join(a.output, "report.md"))
    return EXIT_OK


def main(argv=None) -> int:
    """Entry point of the ``warp-tube`` console script; returns the exit status."""
    args = _parser().parse_args(argv)
    args.argv = list(sys.argv[2:] if argv is None else argv[1:])
    import warp as wp

    wp.config.log_level = wp.LOG_INFO if args.verbose else wp.LOG_WARNING
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        handler = {"run": _cmd_run, "check": _cmd_check, "extract": _cmd_extract, "preview": _cmd_preview, "export": _cmd_export, "bench": _cmd_bench}
        return handler[args.command](args)
    except SceneError as e:
        print(f"warp-tube: {e}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("warp-tube: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
