"""The ``wrt`` command: a thin dispatcher (parse, call, report). User errors exit with code 2.

The library's own verbs are here: ``render``, ``rays``, ``stress``. Other installed packages add
verbs through entry points of the group ``wrt.commands`` (the harness: ``matrix``, ``refs``,
``compare``; the benchmarks: ``bench``): an entry point is a function that adds its subparser and
returns the function that runs it. They are looked up only when the verb is not the library's
(or for ``wrt --help``), so ``wrt render`` loads nothing else, and nothing here imports them.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import errno
import gc
import os
import re
import signal
import sys
import threading
import time

from .console import Terminated, terminate
from .errors import SceneError, WrtError
from .limits import MAX_DEPTH, MAX_IMAGE_SIDE, MAX_SEED, MAX_SPP

MAX_CAPACITY = 1 << 24
"""Most segments ``wrt rays --capacity`` may reserve: 92 bytes each, 1.5 GiB in all."""
MAX_THREADS = 1024
MAX_STRESS_RAYS = 10**8
INT32_MAX = 2**31 - 1


def int_in(lo: int | None, hi: int, option: str, key: str | None = None):
    """The argparse ``type`` of an integer option: an integer in ``[lo, hi]``.

    Text that is not an integer is argparse's own error (usage, ``invalid int value``, exit 2). An
    integer out of range raises ``WrtError``, which argparse passes on and ``main`` prints as one
    line naming the option and the value (exit 2), before any work: ``command line:
    render.KEY = V: must be in [lo, hi] (OPTION)`` for an option that overrides the ``[render]`` key
    ``key`` (the loader's range and words), else ``OPTION V: must be >= lo`` (or ``<= hi``).
    ``lo`` None: no lower bound here, the library checks it (with the image size, say).
    """

    def parse(text: str) -> int:
        value = int(text)  # ValueError: argparse's "invalid int value"
        if (lo is None or lo <= value) and value <= hi:
            return value
        if key is not None:
            raise SceneError("command line", "render", key, f"must be in [{lo}, {hi}] ({option})", value)
        raise WrtError(f"{option} {value}: must be " + (f">= {lo}" if lo is not None and value < lo else f"<= {hi}"))

    parse.__name__ = "int"  # argparse names the type in "invalid int value"
    parse.range = (lo, hi)
    return parse


def finite_float(lo: float, hi: float, option: str):
    """The argparse ``type`` of a real-valued option: a finite number in ``[lo, hi]`` (NaN, Inf and
    1e308 are refused as one line naming the option and the value)."""

    def parse(text: str) -> float:
        value = float(text)  # ValueError: argparse's "invalid float value"
        if lo <= value <= hi:
            return value
        raise WrtError(f"{option} {text}: must be a finite number in [{lo:g}, {hi:g}]")

    parse.__name__ = "float"
    return parse


DEVICE_NAME = re.compile(r"cpu|cuda(:\d{1,4})?")


def device_name(text: str) -> str:
    """The argparse ``type`` of ``--device``: ``cpu``, ``cuda`` or ``cuda:N`` (whether Warp has
    that device is checked when it is used)."""
    if DEVICE_NAME.fullmatch(text):
        return text
    raise argparse.ArgumentTypeError(f"invalid device {text!r} (use cpu, cuda or cuda:N)")


def add_device_option(parser: argparse.ArgumentParser) -> None:
    """``--device cpu|cuda|cuda:N``, the same in every verb."""
    parser.add_argument("--device", type=device_name, default="cpu", help="Warp device: cpu (default), cuda or cuda:N")


AOV_CHOICES = {
    "depth": "depth",
    "normal": "normal",
    "id": "object_id",
    "object_id": "object_id",
    "position": "position",
}


def _aov_list(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == ["all"]:
        return ["depth", "normal", "object_id", "position"]
    unknown = [n for n in names if n not in AOV_CHOICES]
    if unknown or not names:
        raise argparse.ArgumentTypeError(
            f"unknown AOV {unknown[0] if unknown else text!r} (choose from depth, normal, id, position, or all)"
        )
    return list(dict.fromkeys(AOV_CHOICES[n] for n in names))


PLUGIN_GROUP = "wrt.commands"


class Parser(argparse.ArgumentParser):
    """argparse with the CLI's error convention: a bad option or argument is one escaped line,
    ``prog: error: <message>`` (``report_error``), and exit code 2; ``--help`` shows the usage."""

    def error(self, message: str):
        report_error(WrtError(message), prog=self.prog)
        sys.exit(2)


def _parser(plugins: bool) -> tuple[argparse.ArgumentParser, dict]:
    """The parser, and the run function of each verb; with ``plugins``, the verbs of the
    ``wrt.commands`` entry points too."""
    parser = Parser(prog="wrt", description="wrt: a ray tracer whose rendering runs as NVIDIA Warp kernels.")
    verbs = parser.add_subparsers(dest="verb", metavar="VERB", required=True)
    r = verbs.add_parser(
        "render",
        help="render a scene file to an image",
        description="Render a TOML scene file to an EXR (linear float RGB plus optional AOV channels) or PNG "
        "(tone mapped: clipped to [0, 1], sRGB, 8 bit). Options override the scene's [render] table. With spp > 1 "
        "it renders in passes of about a second, with a progress bar on a terminal; Ctrl-C (or SIGTERM) stops at the "
        "next image tile and writes the samples of the passes done (exit code 130, 143 for SIGTERM; a second signal "
        "aborts without writing).",
    )
    r.add_argument("scene", help="scene file: .toml (docs/scene-format.md) or Mitsuba 3 .xml (docs/mitsuba.md)")
    fidelity = r.add_mutually_exclusive_group()
    fidelity.add_argument(
        "--approximate",
        action="store_true",
        help="Mitsuba XML: convert what wrt cannot render exactly as Mitsuba anyway (listed on stderr and in the "
        "EXR metadata 'approximations'); by default such a scene is refused",
    )
    fidelity.add_argument("--strict", action="store_true", help="Mitsuba XML: refuse inexact conversions (the default)")
    r.add_argument("-o", "--output", required=True, help="output image, .exr or .png (written atomically)")
    r.add_argument(
        "--spp", type=int_in(1, MAX_SPP, "--spp", "spp"), help="samples per pixel (default: the scene's [render] spp)"
    )
    r.add_argument(
        "--seed", type=int_in(0, MAX_SEED, "--seed", "seed"), help="random seed (default: the scene's [render] seed)"
    )
    r.add_argument(
        "--sampler",
        choices=("independent", "stratified", "sobol"),
        help="random numbers (default: the scene's [render] sampler)",
    )
    r.add_argument(
        "--max-depth",
        type=int_in(1, MAX_DEPTH, "--max-depth", "max_depth"),
        help="ray segments per path, camera ray included (default: the scene's [render] max_depth)",
    )
    r.add_argument(
        "--width",
        type=int_in(1, MAX_IMAGE_SIDE, "--width", "width"),
        help="image width in pixels (default: the scene's)",
    )
    r.add_argument(
        "--height",
        type=int_in(1, MAX_IMAGE_SIDE, "--height", "height"),
        help="image height in pixels (default: the scene's)",
    )
    add_device_option(r)
    r.add_argument(
        "--threads",
        type=int_in(1, MAX_THREADS, "--threads"),
        help=f"CPU threads launching image tiles, at most {MAX_THREADS} (default: all cores)",
    )
    r.add_argument(
        "--aov",
        type=_aov_list,
        default=[],
        help="comma-separated AOVs to add as EXR channels: depth (Z), normal (N.X,N.Y,N.Z), id (id), "
        "position (P.X,P.Y,P.Z), or all",
    )
    r.add_argument("--half", action="store_true", help="store EXR RGB as half floats (AOVs stay float32)")
    r.add_argument(
        "--target-error",
        type=finite_float(0.0, 1e6, "--target-error"),
        metavar="E",
        help="adaptive sampling: a pixel stops once the estimated relative standard error of its mean luminance is "
        "below E (e.g. 0.02); --spp is then the most a pixel takes, and an EXR output gets the per-pixel sample count "
        "as channel 'spp'",
    )
    r.add_argument(
        "--checkpoint-every",
        type=int_in(1, MAX_SPP, "--checkpoint-every"),
        metavar="N",
        help="also write the image to the output every N samples per pixel (its metadata spp: the samples done)",
    )
    r.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="render on the Dask distributed cluster whose scheduler is at ADDRESS (tcp://host:8786), in pixel tiles: "
        "the same image, bit for bit (needs the cluster extra; see docs/cluster.md)",
    )

    rays = verbs.add_parser(
        "rays",
        help="show the rays traced for chosen pixels in 3D",
        description="Trace chosen pixels with the scene's integrator, recording every ray the render kernels trace "
        "(camera, shadow, reflected, refracted, totally internally reflected; with the light tracer, the light paths "
        "of the pixels' slots and their connections to the camera), and draw the ray trees with pyvista "
        "over the scene geometry, write them as an interactive web page, or export them as a VTK multiblock. See "
        "docs/rays.md.",
    )
    rays.add_argument("scene", help="scene file (.toml)")
    rays.add_argument(
        "--pixel",
        nargs=2,
        type=int_in(-INT32_MAX, INT32_MAX, "--pixel"),  # checked against the image by wrt.rays
        action="append",
        default=[],
        metavar=("X", "Y"),
        help="a pixel to trace (row 0 at the top); repeatable",
    )
    rays.add_argument(
        "--grid",
        nargs=2,
        type=int_in(1, MAX_IMAGE_SIDE, "--grid"),
        metavar=("NX", "NY"),
        help="also trace the centre pixels of an NX x NY grid over the image",
    )
    rays.add_argument(
        "--samples",
        type=int_in(None, MAX_SPP, "--samples"),  # >= 1: wrt.rays says so
        default=1,
        help="samples per pixel (default 1: the pixel centre)",
    )
    rays.add_argument(
        "--max-depth",
        "--depth",
        dest="max_depth",
        type=int_in(1, MAX_DEPTH, "--max-depth", "max_depth"),
        help="ray segments per path, camera ray included (default: the scene's [render] max_depth)",
    )
    shown = rays.add_mutually_exclusive_group(required=True)
    shown.add_argument("-o", "--output", help="render the view off screen to this .png")
    shown.add_argument("--interactive", action="store_true", help="open a window (needs a display)")
    shown.add_argument("--export", help="write a VTK multiblock (.vtm) for ParaView or pyvista.read")
    shown.add_argument(
        "--html",
        help="write one self-contained interactive page (.html): turn and zoom the view in any browser, offline",
    )
    rays.add_argument(
        "--view",
        nargs=2,
        type=finite_float(-360.0, 360.0, "--view"),
        metavar=("AZIMUTH", "ELEVATION"),
        help="view angles in degrees relative to the scene camera (default: automatic)",
    )
    add_device_option(rays)
    rays.add_argument(
        "--capacity",
        type=int_in(1, MAX_CAPACITY, "--capacity"),
        default=1 << 18,
        help=f"segments the record buffer holds, 92 bytes each (default 262144, at most {MAX_CAPACITY})",
    )
    rays.add_argument(
        "--show-bvh", action="store_true", help="also draw the BVH boxes each traced ray's closest-hit query visited"
    )

    st = verbs.add_parser(
        "stress",
        help="run the numerical stress suite",
        description="Shoot adversarial rays through the real kernels (watertightness, self-intersection, sphere "
        "precision, float32 vs float64, grazing and degenerate geometry, refraction, NaN/Inf) and print a table: "
        "case, rays, failures, worst error, bound. Exit 0 when every case passes, 1 otherwise. See docs/stress.md.",
    )
    st.add_argument(
        "--rays",
        type=int_in(1, MAX_STRESS_RAYS, "--rays"),
        default=10**6,
        help=f"rays per ray-batch case (default 1000000, at most {MAX_STRESS_RAYS})",
    )
    st.add_argument("--seed", type=int_in(0, MAX_SEED, "--seed"), default=0, help="random seed (default 0)")
    st.add_argument("--report", metavar="DIR", help="also write the table as DIR/stress.json and DIR/stress.md")
    k = verbs.add_parser(
        "kernels",
        help="list the Warp modules scenes need; compile them; rebuild the shipped ones",
        description="List the Warp kernel modules that scenes need (default: every example scene, which the "
        "matrix renders), with their generated source and object sizes, compile time and state: shipped "
        "(compiled ahead of time, in the package), cached (in Warp's kernel cache) or to compile (on first use). "
        "See docs/performance.md.",
    )
    k.add_argument(
        "scenes", nargs="*", metavar="SCENE", help="scene files (.toml or Mitsuba .xml; default: the examples)"
    )
    k.add_argument(
        "--compile",
        action="store_true",
        help="compile the modules that are not cached, --jobs at a time, and time each",
    )
    k.add_argument(
        "--ship",
        nargs="?",
        const="",
        metavar="DIR",
        help="rebuild the shipped modules: compile every module for the portable CPU target, and the core ones to "
        "PTX for CUDA, and write cpu.zip, cuda.zip and manifest.json to DIR (default: the package's "
        "kernels/compiled); after editing a kernel",
    )
    k.add_argument(
        "--jobs", type=int_in(1, MAX_THREADS, "--jobs"), help="modules compiled at once (default: one per core)"
    )
    runs = {"render": _render, "rays": _rays, "stress": _stress, "kernels": _kernels}
    if plugins:
        from importlib.metadata import entry_points

        for ep in sorted(entry_points(group=PLUGIN_GROUP), key=lambda e: e.name):
            runs[ep.name] = ep.load()(verbs)
    return parser, runs


def _interruption(signum: int) -> KeyboardInterrupt:
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


SIGNAL_GRACE_S = 1.0
"""A signal this soon after the first is the same request: one Ctrl-C under ``timeout`` arrives
twice, from the terminal and forwarded by ``timeout``."""


class StopRequest:
    """The render's handling of Ctrl-C (SIGINT) and SIGTERM, as a context.

    Within it, the first signal sets ``event`` (a render then stops at its next tile and writes
    the samples done) and records ``signum``; a repeat within ``SIGNAL_GRACE_S`` is the same
    request. A later one ends the process as usual (``KeyboardInterrupt`` or ``Terminated``),
    except while a file is being written (``writing``): then the write completes first. The
    previous handlers come back when the context ends.
    """

    def __init__(self):
        self.event = threading.Event()
        self.signum = 0
        self._first = 0.0
        self._writing = False
        self._deferred = 0

    def _handle(self, signum, frame):
        now = time.monotonic()
        if not self.event.is_set():
            self.signum, self._first = signum, now
            self.event.set()
        elif now - self._first < SIGNAL_GRACE_S:
            return
        elif self._writing:
            self._deferred = signum
        else:
            raise _interruption(signum)

    @contextlib.contextmanager
    def writing(self):
        """Within: a file is being written, and no signal interrupts it; one that asked to end the
        process does so once the write is done."""
        self._writing = True
        try:
            yield
        finally:
            self._writing = False
        if self._deferred:
            raise _interruption(self._deferred)

    def __enter__(self) -> StopRequest:
        self._previous = {signum: signal.signal(signum, self._handle) for signum in (signal.SIGINT, signal.SIGTERM)}
        return self

    def __exit__(self, *exc) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)


def _render(args) -> int:
    from tqdm import tqdm

    from . import __version__
    from .device import init_warp
    from .files import check_writable
    from .imageio import half_overflow, write_image
    from .loader import load_scene, override_render
    from .renderer import render

    if args.target_error is not None and not args.target_error > 0.0:
        raise WrtError(f"--target-error {args.target_error}: must be > 0")
    ext = os.path.splitext(args.output)[1].lower()
    if ext not in (".exr", ".png"):
        raise WrtError(f"{args.output}: unsupported output format {ext or '(none)'!r} (use .exr or .png)")
    for option, given in (("--aov", args.aov), ("--half", args.half)):
        if given and ext != ".exr":
            raise WrtError(f"{args.output}: {option} needs an .exr output")
    if args.scheduler is not None and args.target_error is not None:
        raise WrtError("--target-error: adaptive sampling runs locally only, not with --scheduler")
    if args.scheduler is not None and args.threads is not None:
        raise WrtError("--threads: not with --scheduler (each worker thread renders one tile at a time)")
    check_writable(args.output, protect=(args.scene,))  # before the work, not after it
    messages = init_warp()
    if args.device.startswith("cuda") and args.scheduler is None and messages:  # with a scheduler: the workers' GPUs
        print(messages, end="", file=sys.stderr)
    scene = override_render(
        load_scene(args.scene, approximate=args.approximate),
        width=args.width,
        height=args.height,
        spp=args.spp,
        seed=args.seed,
        sampler=args.sampler,
        max_depth=args.max_depth,
    )
    pixels = scene.render.width * scene.render.height
    cluster = contextlib.nullcontext()
    if args.scheduler is not None:
        from .distributed import Cluster

        cluster = Cluster(args.scheduler)

    def write(result) -> None:
        metadata = {
            "version": __version__,
            "scene": os.path.abspath(args.scene),
            "spp": result.spp,
            "seed": result.seed,
            "integrator": result.integrator,
            "device": result.device,
            "render_time_s": result.render_time_s,
        }
        if scene.approximations:  # what an --approximate Mitsuba import rendered differently
            metadata["approximations"] = "\n".join(scene.approximations)
        aovs = {k: result.aovs[k] for k in args.aov}
        if args.target_error is not None and ext == ".exr":
            aovs["spp"] = result.aovs["spp"].astype("float32")  # counts are exact in float32
            metadata["target_error"] = args.target_error
        write_image(args.output, result.rgb, aovs=aovs, metadata=metadata, half=args.half)

    bar = tqdm(
        total=scene.render.spp,
        desc="rendering",
        bar_format="{desc} {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} spp{postfix}",
        file=sys.stderr,
        disable=True if scene.render.spp == 1 else None,  # None: shown on a terminal only
    )
    with cluster, bar, StopRequest() as request:
        stop = request.event

        def on_pass(done: int, spp: int, elapsed: float, snapshot) -> bool:
            if args.target_error is None:
                rate = done / max(elapsed, 1e-9)  # spp per second
                eta = tqdm.format_interval((spp - done) / rate)
                bar.set_postfix_str(
                    f"{tqdm.format_interval(elapsed)}<{eta}, {rate * pixels / 1e6:.3g} M samples/s", refresh=False
                )
            else:  # fewer pixels each pass: no rate or ETA to promise
                bar.set_postfix_str(f"{tqdm.format_interval(elapsed)}, adaptive", refresh=False)
            bar.update(done - bar.n)
            if args.checkpoint_every and done % args.checkpoint_every == 0 and done < spp and not stop.is_set():
                with request.writing():
                    write(snapshot())
            return not stop.is_set()

        options = {"device": args.device, "progress": on_pass, "progress_every": args.checkpoint_every, "stop": stop}
        if args.scheduler is None:
            result = render(scene, threads=args.threads, target_error=args.target_error, **options)
        else:
            result = cluster.render(scene, **options)
        what = "interrupted" if request.signum == signal.SIGINT else "terminated"  # when a signal came
        if result.spp == 0:  # a signal before the first pass ended: no sample to write
            print(f"wrt: {what} before the first pass ended: nothing written", file=sys.stderr)
            return 128 + request.signum
        with request.writing():
            write(result)
    h, w = result.rgb.shape[:2]
    samples = int(result.aovs["spp"].sum()) if "spp" in result.aovs else result.spp * pixels  # adaptive: as taken
    adaptive = f" (adaptive: {samples / pixels:.1f} on average)" if "spp" in result.aovs else ""
    print(
        f"wrote {args.output}: {w}x{h}, {result.spp} spp{adaptive}, {result.integrator}, {result.device} "
        f"({result.threads} thread{'s' if result.threads > 1 else ''}); BVH {result.build_time_s:.2f} s, "
        f"kernels {result.compile_time_s:.2f} s, render {result.render_time_s:.3f} s "
        f"({samples / max(result.render_time_s, 1e-9) / 1e6:.3g} M samples/s)"
    )
    if args.half and half_overflow(result.rgb):
        print(
            f"wrt: warning: {half_overflow(result.rgb)} radiance values exceed 65504, the largest half float, and "
            "were stored as 65504 (--half)",
            file=sys.stderr,
        )
    if result.rejected_samples:
        print(
            f"wrt: warning: {result.rejected_samples} samples were NaN or Inf (or entered more than 8 nested "
            "dielectrics) and were taken as black",
            file=sys.stderr,
        )
    if request.signum:  # a signal, not adaptive sampling's early convergence
        print(f"wrt: {what}: wrote the {result.spp} of {scene.render.spp} spp done", file=sys.stderr)
        return 128 + request.signum
    return 0


def _rays(args) -> int:
    from . import rayview

    if not args.pixel and not args.grid:
        raise WrtError("give at least one --pixel X Y or a --grid NX NY")
    return rayview.run(
        args.scene,
        [tuple(p) for p in args.pixel],
        grid=args.grid,
        samples=args.samples,
        max_depth=args.max_depth,
        output=args.output,
        interactive=args.interactive,
        export_path=args.export,
        html_path=args.html,
        view=args.view,
        device=args.device,
        capacity=args.capacity,
        show_bvh=args.show_bvh,
    )


def _stress(args) -> int:
    from . import stress

    return stress.command(args.rays, args.seed, args.report)


def _kernels(args) -> int:
    from . import aot
    from .tables import text_table

    scenes = args.scenes or [aot.example_path(f) for f in aot.example_scenes()]
    for scene in args.scenes:
        if not os.path.isfile(scene):
            raise WrtError(f"{scene}: no such scene file")

    def done(name: str, seconds: float) -> None:
        print(f"  {name}: {seconds:.1f} s", file=sys.stderr, flush=True)

    if args.ship is not None:
        folder = args.ship or aot.SHIPPED_DIR
        manifest = aot.ship(scenes, folder, args.jobs, progress=done)
        size = sum(m["object_bytes"] for m in manifest["modules"])
        ptx = sum(m["ptx_bytes"] for m in manifest["cuda"]["modules"])
        zipped = {kind: os.path.getsize(os.path.join(folder, name)) / 1e6 for kind, name in aot.ARCHIVES.items()}
        print(
            f"wrote {len(manifest['modules'])} CPU modules ({size / 1e6:.1f} MB of objects, {zipped['cpu']:.1f} MB "
            f"zipped) and {len(manifest['cuda']['modules'])} CUDA modules (sm_{manifest['cuda']['arch']} PTX, "
            f"{ptx / 1e6:.1f} MB, {zipped['cuda']:.1f} MB zipped) to {folder} in {manifest['wall_s']:.0f} s"
        )
        return 0
    modules = aot.needed_modules(scenes)
    if not args.scenes:  # the shipped set: the examples' and the listed variants
        modules |= aot.listed_variants()
    seconds = {}
    if args.compile:
        missing = {n: m for n, m in modules.items() if not aot.cache_entry(m, "cpu").cached()}
        seconds = aot.compile_modules(missing, args.jobs, done)
    rows = [{**r, "compile_s": seconds[r["name"]]} if r["name"] in seconds else r for r in aot.table(modules)]
    table = [["module", "state", "source KB", "object KB", "compile s"]]
    for r in rows:
        sizes = [f"{r[k] / 1024:.0f}" if k in r else "-" for k in ("source_bytes", "object_bytes")]
        table.append([r["name"], r["state"], *sizes, f"{r['compile_s']:.1f}" if "compile_s" in r else "-"])
    print(text_table(table, right={2, 3, 4}))
    states = {s: sum(r["state"] == s for r in rows) for s in ("shipped", "cached", "to compile")}
    print(f"{len(rows)} modules: " + ", ".join(f"{n} {s}" for s, n in states.items()))
    return 0


LIBRARY_VERBS = ("render", "rays", "stress", "kernels")


def run_verb(run, args: argparse.Namespace, prog: str = "wrt") -> int:
    """Run a verb's function: its exit code; a ``WrtError`` is one line on stderr and exit code 2,
    an interruption exit code 130 (SIGTERM: 143). Warp is initialised first (``render`` does it
    itself, to show its messages only for CUDA)."""
    try:
        if args.verb != "render":
            from .device import init_warp

            init_warp()
        return run(args)
    except WrtError as e:
        return report_error(e, prog)
    except KeyboardInterrupt as e:
        return interrupted(e, prog)


def interrupted(e: KeyboardInterrupt, prog: str = "wrt") -> int:
    """Say that Ctrl-C (or SIGTERM, ``Terminated``) ended the command; its exit code, 130 (143)."""
    print(f"{prog}: {'terminated' if isinstance(e, Terminated) else 'interrupted'}", file=sys.stderr)
    return 128 + (signal.SIGTERM if isinstance(e, Terminated) else signal.SIGINT)


_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f]")


def report_error(error: WrtError, prog: str = "wrt") -> int:
    """Print ``prog: error: <message>`` as one line on stderr; return exit code 2.

    The one place the CLI prints errors. Control characters (C0, DEL, C1: a newline, or ESC
    sequences from a file name or a value, which would reach the terminal raw) are written as
    ``\\xNN`` escapes.
    """
    message = _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", str(error))
    print(f"{prog}: error: {message}", file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser, runs = _parser(plugins=not (argv and argv[0] in LIBRARY_VERBS))
    try:
        args = parser.parse_args(argv)
    except WrtError as e:  # an integer option out of range (int_in)
        return report_error(e)
    return run_verb(runs[args.verb], args)


class GuardedStdout:
    """Standard output that cannot end a command that has done its work: a write that fails (a
    closed pipe, ``| head -0``; a full disk, ``> /dev/full``) is recorded, output is dropped from
    then on, and file descriptor 1 is pointed at ``/dev/null`` so that no later flush fails again."""

    def __init__(self, stream):
        self.stream = stream
        self.error: OSError | None = None

    def write(self, text: str) -> int:
        if self.error is None:
            try:
                return self.stream.write(text)
            except OSError as e:
                self._failed(e)
        return len(text)

    def flush(self) -> None:
        if self.error is None:
            try:
                self.stream.flush()
            except OSError as e:
                self._failed(e)

    def _failed(self, error: OSError) -> None:
        self.error = error
        with contextlib.suppress(OSError, ValueError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self.stream.fileno())
            os.close(devnull)

    def __getattr__(self, name):
        return getattr(self.stream, name)


def console() -> int:
    """The ``wrt`` command: :func:`main` in a process of its own.

    - SIGTERM is handled like Ctrl-C from the first moment (``Terminated``), and either one during
      start-up or a verb is one line and exit code 130 (143), never a traceback.
    - Standard output is guarded (``GuardedStdout``): when it cannot be written, the command
      still finishes its work; a closed pipe is silent, another error (a full disk) one line on
      stderr and exit code 1 where the command would have exited 0.
    - What is alive once wrt's core is imported (modules, Warp's builtins, the kernels' parsed
      functions) lives as long as the process: frozen, it is left out of the cyclic collector's
      full passes, each of which would otherwise scan it again (about 50 ms of a one-second
      render). It is unfrozen at exit, so that shutdown frees it as usual.
    """
    signal.signal(signal.SIGTERM, terminate)
    stdout = sys.stdout = GuardedStdout(sys.stdout)
    try:
        import wrt

        wrt.render, wrt.load_scene  # noqa: B018 (the core, imported with the collector paused)
        gc.freeze()
        atexit.register(gc.unfreeze)
        code = main()
        stdout.flush()
    except KeyboardInterrupt as e:
        code = interrupted(e)
    if stdout.error is not None and stdout.error.errno != errno.EPIPE:
        print(f"wrt: error: cannot write to standard output ({stdout.error.strerror})", file=sys.stderr)
        code = code or 1
    return code


if __name__ == "__main__":  # python -m wrt.cli: as python -m wrt, through the entry point that handles signals first
    from .console import main as _main

    sys.exit(_main())
