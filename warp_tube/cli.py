"""Command line: ``warp-tube run | check | extract | preview | export | batch | bench``.

Exit status: 0 done; 1 internal error (a bug: the message says so, ``-v`` shows the traceback);
2 invalid input or request (message, no traceback, nothing simulated, no output file) or an output
that cannot be written; 3 numerical failure; 130 interrupted (Ctrl-C; 143 SIGTERM, 129 SIGHUP). A run that stops early keeps the
frames finished so far in ``OUT.partial.usdc`` beside ``OUT`` and says so; ``OUT`` is left as it was.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import time
import traceback
from importlib import resources

from .runtime.interrupts import exit_status, import_whole, stopped_by, terminate_as_interrupt
from .scene.spec import SceneError

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_NUMERICAL = 0, 1, 2, 3
#: model set-up time per centerline point [s] (build_model and the surface topology, measured by
#: benchmarks/bench_estimates.py: 2-3 us on one CPU core, 5,000 to 200,000 points), for the up-front
#: warning of a long build.
BUILD_SECONDS_PER_POINT = 4e-6
#: a build estimated to take longer than this [s] is announced.
LONG_BUILD_SECONDS = 30.0

log = logging.getLogger("warp_tube.cli")


def default_scene_path() -> str:
    """Path of the embedded default scene (a clamped tube bent by a time-varying push)."""
    return str(resources.files("warp_tube") / "data" / "default.usda")


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.print_usage(sys.stderr)
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        sys.exit(EXIT_INPUT)


def _version() -> str:
    from .version import __version__

    return __version__


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="warp-tube", description="Simulate tube-shaped soft bodies: USD scene in, time-sampled USD out.")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="show details: info messages, Warp's start-up and module-load lines, tracebacks of internal errors")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    r = sub.add_parser("run", allow_abbrev=False, help="simulate a scene and write a time-sampled USD stage",
                       description="Simulate the tubes of a USD scene and write their Centerline and Surface as a "
                       "time-sampled USD stage; prints a summary.")
    r.add_argument("scene", nargs="?", help="scene .usda/.usdc (default: the embedded default scene)")
    r.add_argument("-o", "--output", help="output stage (.usdc, .usda); default: <scene name>.out.usdc here "
                   "(tube.usdc for the embedded scene)")
    r.add_argument("--device", help="cpu or cuda:N (default: CUDA when available)")
    r.add_argument("--frames", type=int, help="frames to simulate, frame 0 (rest) included (default: the scene's)")
    r.add_argument("--every", type=int, default=1, help="write every K-th of them (frame 0 always; default 1: every frame)")
    r.add_argument("--no-surface", action="store_true", help="write the Centerline only")
    r.add_argument("--quiet", action="store_true", help="no progress bar, no summary")

    c = sub.add_parser("check", allow_abbrev=False, help="validate a scene without simulating",
                       description="Validate a scene as run does, without simulating or writing anything.")
    c.add_argument("scene", help="scene .usda/.usdc to validate")

    e = sub.add_parser("extract", help="extract a tube scene from a surface mesh (STL, PLY, OBJ, OFF, glTF binary)",
                       description="Extract a tube's centerline and spoke lengths from a segmented surface mesh into a "
                       "scene (metres) with a push sized to move it by two radii.")
    e.add_argument("mesh", help="tube surface mesh: .stl, .ply, .obj, .off or .glb")
    e.add_argument("-o", "--output", required=True, help="scene to write: .usda (text), .usdc or .usd (binary)")
    e.add_argument("--hubs", type=int, help="centerline points (default: from length and radius)")
    e.add_argument("--spokes", type=int, help="spokes per hub (default 16; 32 for sections flatter than 3.5:1)")
    e.add_argument("--scale", type=float, nargs="+", metavar="F", help="F, or FX FY FZ: metres per mesh unit (default 1: the mesh is in metres)")
    e.add_argument("--strict", action="store_true", help="refuse a mesh that is not tube-like instead of warning")

    v = sub.add_parser("preview", allow_abbrev=False, help="render a contact sheet of an output stage to PNG",
                       description="Render evenly spaced frames of an output stage's Surface meshes side by side into a "
                       "PNG (320 x 320 pixels a tile, 8 tiles a row); each tile after the first shows frame 0 in "
                       "light grey behind, so the motion shows.")
    v.add_argument("stage", help="output stage written by run or batch (.usdc, .usda)")
    v.add_argument("-o", "--output", required=True, help="PNG to write")
    v.add_argument("--frames", type=int, help="frames on the sheet, the first and last included (default 4)")

    x = sub.add_parser("export", allow_abbrev=False, help="export an output stage's Surface as OBJ or glTF binary",
                       description="Write the Surface meshes of an output stage, one file per frame, for tools "
                       "without USD (OBJ in the stage's units and up axis; glTF binary in metres, Y up).")
    x.add_argument("stage", help="output stage written by run or batch (.usdc, .usda)")
    x.add_argument("--format", choices=("obj", "glb"), help="file format (default: the suffix of -o FILE, else obj)")
    x.add_argument("-o", "--output", help="folder for the files, or one file with --frame (default: a folder "
                   "<stage name>_<format> beside the stage; with --frame, the file beside the stage)")
    x.add_argument("--frame", type=float, help="only this time code (default: every frame)")
    x.add_argument("--force", action="store_true", help="replace existing files (default: an existing file is an error)")

    from .batch.command import add_parser as add_batch_parser

    add_batch_parser(sub)

    b = sub.add_parser("bench", help="speed against error beside peer simulators; results, report and plots",
                       description="Time to the answer, accuracy and throughput of warp_tube beside PyElastica and "
                       "Newton (those installed), each in its own process; writes results.json, report.md and "
                       "PNG plots (with matplotlib) into -o DIR.")
    b.add_argument("-o", "--output", help="folder for results.json, report.md and the plots; required (with --replot: "
                   "default the results' own folder)")
    b.add_argument("--suite", choices=("accuracy", "speed", "all"), default="all",
                   help="accuracy: cantilevers, frequency, curved tube; speed: throughput of 1 to 65,536 tubes "
                   "(default all)")
    b.add_argument("--peers", help="pyelastica,newton (default: both where installed) or none")
    b.add_argument("--device", help="cpu or cuda:N (default: CUDA when available)")
    b.add_argument("--quick", action="store_true", help="the small problem set (tests, a first look)")
    b.add_argument("--repeat", type=int, help="interleaved repetitions (default 3; 1 with --quick)")
    b.add_argument("--replot", metavar="RESULTS", help="only rewrite report and plots from an earlier results.json")
    p.commands = sub.choices  # each command's parser, by name
    for command in sub.choices.values():  # -v after the command too (warp-tube run -v ...)
        command.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                             help="as warp-tube -v: info messages, Warp's start-up lines, tracebacks of internal errors")
    return p


def _cmd_run(a) -> int:
    from . import load_scene
    from .scene.files import default_run_output, usd_layer_files
    from .io.writer import check_output_path
    from .runtime.progress import Phase, PlainProgress, format_seconds, stderr_is_terminal
    from .scene.usd import open_stage
    from .sim.simulation import NumericalError, Simulation

    scene_path = a.scene or default_scene_path()
    if a.frames is not None and a.frames < 1:
        raise SceneError(f"--frames {a.frames}: expected at least 1")
    if a.every < 1:
        raise SceneError(f"--every {a.every}: expected at least 1")
    tty = stderr_is_terminal() and not a.quiet
    t_read = time.perf_counter()
    with Phase("reading the scene", enabled=tty):
        held = open_stage(scene_path)  # held open while loading: its layers are read once
        inputs = [scene_path, *usd_layer_files(held)]
        out = check_output_path(a.output if a.output is not None else default_run_output(a.scene), inputs)
        scene = load_scene(scene_path)
        del held
    points = sum(len(t.points) for t in scene.tubes)
    if points * BUILD_SECONDS_PER_POINT > LONG_BUILD_SECONDS:
        log.warning("building the model of %s points will take about %s (set-up in Python, point by point)",
                    f"{points:,}", format_seconds(points * BUILD_SECONDS_PER_POINT))  # fmt: skip
    info = scene.stage
    unauthored = [k for k in ("endTimeCode", "startTimeCode") if k not in info.authored]
    if a.frames is None and info.frame_count == 1 and unauthored:
        log.warning("%s: %s not authored: taken as the %s (%g), which gives one frame and nothing to simulate; "
                    "author %s or pass --frames N", scene_path or "the scene", unauthored[0],
                    "start" if unauthored[0] == "endTimeCode" else "end", info.end_time_code, unauthored[0])  # fmt: skip
    elif a.frames is None and info.frame_count == 1:
        start, end = info.start_time_code, info.end_time_code
        span = (f"startTimeCode and endTimeCode are both {start:g}" if end == start else
                f"startTimeCode {start:g} and endTimeCode {end:g} are less than one frame (1 time code) apart")  # fmt: skip
        log.warning("%s: %s, which gives one frame and nothing to simulate; author an "
                    "endTimeCode of at least %g or pass --frames N", scene_path or "the scene", span, start + 1)  # fmt: skip
    # Run warnings go into the summary; with --quiet (no summary unless the run stops) they are
    # printed as they happen instead.
    _RUN_WARNINGS.summary_prints_them = not a.quiet
    with Phase(f"building the model ({points:,} points; its kernels compile on a first run)", enabled=tty):
        sim = Simulation(scene, device=a.device, surface=not a.no_surface)
    try:
        # On a terminal a progress bar; elsewhere (a log file) a plain line every 30 s, unless --quiet.
        progress = tty or (None if a.quiet else PlainProgress())
        summary = sim.run(frames=a.frames, output=out, progress=progress, every=a.every, setup_time=time.perf_counter() - t_read)
    except NumericalError as e:
        return _stopped(sim, out, f"{e}", EXIT_NUMERICAL, a.quiet)
    except KeyboardInterrupt as e:
        s = sim.last_summary
        how = stopped_by(e)
        if s is None or (s.frames == 0 and s.frames_simulated == 0):
            why = f"{how} during start-up (kernel compilation), before any frame was finished"
        else:
            why = f"{how} while simulating frame {s.first_frame + s.frames_simulated + 1}"
        return _stopped(sim, out, why, exit_status(e), a.quiet)
    except SceneError:
        raise
    except OSError as e:  # (a save that failed: one line, no summary of frames that never reached a file)
        return _stopped(sim, out, f"cannot write {out}: {e.strerror or e}", EXIT_INPUT, a.quiet, one_line=True)
    except Exception as e:
        if a.verbose:
            traceback.print_exc()
        return _stopped(sim, out, f"internal error ({type(e).__name__}: {e}); run with -v for the traceback and "
                                  "please report it", EXIT_INTERNAL, a.quiet)  # fmt: skip
    if not a.quiet:
        print(summary.text())
    return EXIT_OK


def _stopped(sim, out: str, why: str, status: int, quiet: bool = False, one_line: bool = False) -> int:
    """Print why a run stopped early (after its summary, unless quiet or ``one_line``) and where
    its frames are (on the same line with ``one_line``)."""
    s = sim.last_summary  # (None where the run stopped before its first frame began)
    if not (quiet or one_line) and s is not None:
        print(s.text(), file=sys.stderr)
    if s is None:
        kept = "no frame was simulated: nothing kept"
    elif s.partial:
        kept = f"{s.frames_written_text()} kept in {s.partial}"
    elif s.frames:
        kept = f"{s.frames_written_text()} could not be saved: nothing kept"
    else:
        kept = "no frame was finished: nothing kept"
    left = f"{out} was left as it was" if os.path.exists(out) else f"{out} was not written"
    if one_line:
        print(f"warp-tube: {why}; {kept}; {left}", file=sys.stderr)
    else:
        print(f"warp-tube: {why}", file=sys.stderr)
        print(f"warp-tube: {kept}; {left}", file=sys.stderr)
    return status


def _cmd_check(a) -> int:
    from . import load_scene

    s = load_scene(a.scene)
    n = sum(len(t.curve_counts) for t in s.tubes)
    if s.settings.time_step is not None:  # a step the scene sets is checked against the stability bound
        from .sim.simulation import Simulation

        Simulation(s, device="cpu", surface=False)  # (warns where it exceeds the bound)
    print(f"{a.scene}: valid: {n} tube(s) in {len(s.tubes)} prim(s), {len(s.forces)} force(s), "
          f"{s.stage.frame_count} frames at {s.stage.time_codes_per_second:g} per second")  # fmt: skip
    return EXIT_OK


def _cmd_extract(a) -> int:
    from .extract.command import extract_to_scene
    from .runtime.log_filters import renamed
    from .runtime.progress import stderr_is_terminal
    from .scene.files import USD_EXTENSIONS, output_path, temp_path, write_atomically

    if a.scale is not None and len(a.scale) not in (1, 3):
        raise SceneError(f"--scale takes 1 or 3 values, got {len(a.scale)}")
    # Written under a hidden name, its push sized there, and renamed only then: a run that fails
    # or is stopped on the way leaves nothing new, and an existing scene as it was.
    final = output_path(a.output, USD_EXTENSIONS, inputs=[a.mesh], what="scene")
    staged = temp_path(final)  # (the name write_atomically writes under)
    done = None
    lines = []  # printed once the scene is in place: a closed stdout (`| head`) must not cost the scene

    def extract_and_size(tmp: str) -> None:
        nonlocal done
        with renamed(tmp, final):  # (what is said of the scene names the file it becomes)
            done = extract_to_scene(a.mesh, a.output, hubs=a.hubs, spokes=a.spokes, scale=a.scale,
                                    progress=stderr_is_terminal(), strict=a.strict, staging=tmp)  # fmt: skip
            lines.append(done.summary())
            lines.extend(_size_push(tmp, os.path.basename(final), stderr_is_terminal()))

    try:
        write_atomically(final, extract_and_size)
    except SceneError as e:
        if done is None:  # (the extraction's own: nothing was made)
            raise
        left = "left as it was" if os.path.lexists(final) else "not written"
        raise SceneError(str(e).replace(staged, final) + f" ({a.output} {left})") from None
    for line in lines:
        print(line)
    return EXIT_OK


def _size_push(scene: str, name: str, progress: bool) -> list:
    """Size the push of the extracted scene at ``scene`` (its final file name ``name``) by
    simulating it (see :mod:`warp_tube.sim.calibrate`); returns the line to print (none if not
    sized), for the caller to print once the scene is in place."""
    from .runtime.progress import Phase
    from .sim.calibrate import PUSH_FRAMES, size_push
    from .sim.simulation import NumericalError

    try:
        with Phase("sizing the push (simulating the ramp and hold)", enabled=progress):
            size = size_push(scene)
    except NumericalError as e:
        logging.getLogger("warp_tube.extract").warning("%s: the push was not sized (the scene failed: %s)", name, e)
        return []
    if size is None:
        return []
    line = (f"{name}: push {size.force_n:.3g} N on the middle hub: the tube moves by "
            f"{size.moved_m * 1e3:.3g} mm by frame {PUSH_FRAMES - 1} (target {size.target_m * 1e3:.3g} mm; "
            f"x{size.factor:.3g} of the straight-beam estimate; {size.runs} runs)")  # fmt: skip
    if not size.within_tolerance and size.at_limit:
        logging.getLogger("warp_tube.extract").warning(
            "%s: the push is held at 1e9 N a component, the most a scene holds, and moves the tube by %.3g mm, not "
            "the %.3g mm it was sized for: a tube this large is likely in other units than metres (--scale)",
            name, size.moved_m * 1e3, size.target_m * 1e3)  # fmt: skip
    elif not size.within_tolerance:
        logging.getLogger("warp_tube.extract").warning(
            "%s: the push moves the tube by %.3g mm, not the %.3g mm it was sized for: the tube does not answer "
            "in proportion to the force (it snaps through or stiffens); edit /World/Push's warptube:force to taste",
            name, size.moved_m * 1e3, size.target_m * 1e3)  # fmt: skip
    return [line]


def _cmd_preview(a) -> int:
    from .io.preview import preview

    from .runtime.progress import Phase

    if a.frames is not None and a.frames < 1:
        raise SceneError(f"--frames {a.frames}: expected at least 1")
    with Phase(f"drawing {a.frames or 'the'} frame(s) of {os.path.basename(a.stage)}"):  # (a status line on a terminal, after 1 s)
        sheet = preview(a.stage, a.output, frames=a.frames)
    print(sheet)
    return EXIT_OK


def _cmd_export(a) -> int:
    from .io.export import export
    from .runtime.progress import Phase

    fmt = a.format
    if fmt is None:  # -o FILE.glb means glTF binary; a folder or anything else: OBJ
        suffix = os.path.splitext(a.output or "")[1].lower().lstrip(".")
        fmt = suffix if suffix in ("obj", "glb") else "obj"
    with Phase(f"exporting the Surface meshes of {os.path.basename(a.stage)} as {fmt.upper()}"):  # (on a terminal, after 1 s)
        paths = export(a.stage, fmt=fmt, out=a.output, frame=a.frame, overwrite=a.force)
    for path in paths:
        print(path)
    return EXIT_OK


def _cmd_batch(a) -> int:
    from .batch.command import run

    return run(a)


class _RunWarningFilter(logging.Filter):
    """Leaves out the log records of run warnings while the run's summary prints them."""

    summary_prints_them = False

    def filter(self, record):
        return not (self.summary_prints_them and getattr(record, "run_warning", False))


_RUN_WARNINGS = _RunWarningFilter()


class _PlainFormatter(logging.Formatter):
    """``warp-tube: warning: message`` (the level in words, no logger name); on a terminal it first
    clears the line, which may hold a status line or a progress bar."""

    def format(self, record):
        from .runtime.progress import stderr_is_terminal

        clear = "\r\033[K" if stderr_is_terminal() else ""
        return f"{clear}warp-tube: {record.levelname.lower()}: {record.getMessage()}"


def _configure_logging(verbose: bool):
    root = logging.getLogger()
    for h in list(root.handlers):
        if getattr(h, "_warp_tube", False):
            root.removeHandler(h)
    handler = logging.StreamHandler(sys.stderr)
    handler._warp_tube = True
    handler.addFilter(_RUN_WARNINGS)
    if verbose:
        handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    else:
        handler.setFormatter(_PlainFormatter())
    root.addHandler(handler)
    root.setLevel(logging.INFO if verbose else logging.WARNING)


def _cmd_bench(a) -> int:
    from .bench.command import parse_peers, replot, run_bench

    if a.replot:
        replot(a.replot, a.output if a.output is not None else (os.path.dirname(a.replot) or "."))
        return EXIT_OK
    if a.output is None:
        raise SceneError("bench: -o DIR is needed: the folder for results.json, report.md and the plots")
    repeat = a.repeat if a.repeat is not None else (1 if a.quick else 3)
    if repeat < 1:
        raise SceneError(f"--repeat {repeat}: expected at least 1")
    peers = parse_peers(a.peers)
    command = "warp-tube bench " + " ".join(a.argv)
    run_bench(a.suite, peers, a.device, a.output, repeat, a.quick, log=lambda m: print(m, file=sys.stderr), command=command)
    print(os.path.join(a.output, "report.md"))
    return EXIT_OK


def console_main() -> int:
    """The ``warp-tube`` console script (and ``python -m warp_tube``): :func:`main`, then interrupts
    ignored while the process ends. The command's outcome is decided and said by then: a Ctrl-C in
    the ~0.3 s of tearing down (threads, Warp's and usd-core's own clean-up) made a complete run
    exit 130 with nothing said."""
    status = main()
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)
    return status


def main(argv=None) -> int:
    """The command line: parse ``argv`` (default ``sys.argv[1:]``), run the command and return the
    exit status (without ending the process: tests call it)."""
    from .runtime.warp_setup import env_verbose, set_verbose

    parser = _parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown:  # named under the command's own usage, which lists its options
        parser.commands[args.command].error(f"unrecognized arguments: {' '.join(unknown)}")
    raw = list(sys.argv[1:] if argv is None else argv)
    args.argv = raw[raw.index(args.command) + 1 :]  # the command's own arguments (after any -v before it)
    set_verbose(args.verbose or env_verbose())
    _configure_logging(args.verbose)
    _RUN_WARNINGS.summary_prints_them = False
    handler = {"run": _cmd_run, "check": _cmd_check, "extract": _cmd_extract, "preview": _cmd_preview, "export": _cmd_export,
               "batch": _cmd_batch, "bench": _cmd_bench}
    plain_stdout = sys.stdout
    sys.stdout = _GuardedStdout(plain_stdout)
    try:
        with terminate_as_interrupt():  # SIGTERM, SIGHUP: stop as after Ctrl-C, keeping what is finished
            if args.command != "bench":  # (usd-core whole before anything: an interrupt in its import broke it)
                import_whole("pxr.Tf", "pxr.Gf", "pxr.Vt", "pxr.Sdf", "pxr.Usd", "pxr.UsdGeom")
            return handler[args.command](args)
    except SceneError as e:
        print(f"warp-tube: {e}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt as e:
        if args.command == "batch":  # (the batch's folder is made once its variants are read)
            from .batch.command import left_behind

            print(f"warp-tube: {stopped_by(e)}; {left_behind(os.path.abspath(args.output))}", file=sys.stderr)
            return exit_status(e)
        again = ""
        if getattr(e, "left", None):  # (bench: its folder is put back as it was, but for these)
            again = f" (but these could not be removed or put back: {', '.join(e.left)})"
        print(f"warp-tube: {stopped_by(e)}; nothing was written{again}", file=sys.stderr)
        return exit_status(e)
    except BrokenPipeError:  # stdout closed by the reader (`| head`): stop quietly, as other tools do
        _stdout_to_devnull()
        return 128 + 13  # SIGPIPE
    except StdoutError as e:  # (a full disk under a redirected log): the files written are as they were said to be
        _stdout_to_devnull()
        print(f"warp-tube: cannot write to standard output ({e.strerror or e}); what the command printed is lost "
              "there", file=sys.stderr)  # fmt: skip
        return EXIT_INPUT
    except Exception as e:
        return _internal_error(args, e)
    finally:
        sys.stdout = plain_stdout


def _internal_error(args, e: BaseException) -> int:
    if args.verbose:
        traceback.print_exc()
    print(f"warp-tube: internal error ({type(e).__name__}: {e}); run with -v for the traceback and please report it",
          file=sys.stderr)  # fmt: skip
    return EXIT_INTERNAL


class StdoutError(OSError):
    """Standard output could not be written (not a closed pipe: a full disk, an I/O error)."""


class _GuardedStdout:
    """``sys.stdout`` whose failed writes raise :class:`StdoutError`, told apart from the errors of
    the files a command writes."""

    def __init__(self, stream):
        self._stream = stream

    def _guard(self, call, *args):
        try:
            return call(*args)
        except BrokenPipeError:
            raise
        except OSError as e:
            raise StdoutError(e.errno, e.strerror) from None

    def write(self, text):
        return self._guard(self._stream.write, text)

    def flush(self):
        return self._guard(self._stream.flush)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _stdout_to_devnull() -> None:
    """Point standard output at the null device, so that Python's own flush at exit does not fail
    again (what waits in its buffer is dropped)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())


if __name__ == "__main__":
    sys.exit(main())
