"""The ``wrt`` command: a thin dispatcher (parse, call, report). User errors exit with code 2."""
from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading

from .errors import WrtError

AOV_CHOICES = {"depth": "depth", "normal": "normal", "id": "object_id", "object_id": "object_id", "position": "position"}


def _aov_list(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == ["all"]:
        return ["depth", "normal", "object_id", "position"]
    unknown = [n for n in names if n not in AOV_CHOICES]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown AOV {unknown[0] if unknown else text!r} (choose from depth, normal, id, position, or all)")
    return list(dict.fromkeys(AOV_CHOICES[n] for n in names))


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="wrt", description="wrt: a ray tracer whose rendering runs as NVIDIA Warp kernels.")
    verbs = parser.add_subparsers(dest="verb", metavar="VERB", required=True)
    r = verbs.add_parser(
        "render",
        help="render a scene file to an image",
        description="Render a TOML scene file to an EXR (linear float RGB plus optional AOV channels) or PNG "
        "(tone mapped: clipped to [0, 1], sRGB, 8 bit). Options override the scene's [render] table. With spp > 1 "
        "it renders in passes of about a second, with a progress bar on a terminal; Ctrl-C stops after the running "
        "pass and writes the samples done (exit code 130; Ctrl-C again aborts without writing).",
    )
    r.add_argument("scene", help="scene file: .toml (docs/scene-format.md) or Mitsuba 3 .xml (docs/mitsuba.md)")
    r.add_argument("--strict", action="store_true", help="Mitsuba XML: unsupported elements are errors, not warnings")
    r.add_argument("-o", "--output", required=True, help="output image, .exr or .png (written atomically)")
    r.add_argument("--spp", type=int, help="samples per pixel (default: the scene's [render] spp)")
    r.add_argument("--seed", type=int, help="random seed (default: the scene's [render] seed)")
    r.add_argument("--sampler", choices=("independent", "stratified", "sobol"), help="random numbers (default: the scene's [render] sampler)")
    r.add_argument("--width", type=int, help="image width in pixels (default: the scene's)")
    r.add_argument("--height", type=int, help="image height in pixels (default: the scene's)")
    r.add_argument("--device", default="cpu", help="Warp device: cpu (default), cuda or cuda:N")
    r.add_argument("--threads", type=int, help="CPU threads launching image tiles (default: all cores)")
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
        type=float,
        metavar="E",
        help="adaptive sampling: a pixel stops once the estimated relative standard error of its mean luminance is below E "
        "(e.g. 0.02); --spp is then the most a pixel takes, and an EXR output gets the per-pixel sample count as channel 'spp'",
    )
    r.add_argument(
        "--checkpoint-every",
        type=int,
        metavar="N",
        help="also write the image to the output every N samples per pixel (its metadata spp: the samples done)",
    )

    m = verbs.add_parser(
        "matrix",
        help="run the feature test matrix (visual regression harness)",
        description="Render every feature of harness/features.toml (or those named), score it by SSIM and a per-pixel "
        "Z-test against its reference and by SSIM of its object ids against a pyvista rasterisation, check "
        "convergence, print a table. Exit 0 when all pass, 1 on a regression, 2 on bad input.",
    )
    m.add_argument("features", nargs="*", metavar="FEATURE", help="feature names (default: all)")
    m.add_argument("--device", default="cpu", help="Warp device: cpu (default), cuda or cuda:N")
    m.add_argument("--jobs", type=int, default=1, help="features rendered at once (default 1; each uses all cores)")
    m.add_argument("--report", metavar="DIR", help="write an HTML report (DIR/index.html and PNGs)")

    refs = verbs.add_parser("refs", help="regenerate or calibrate reference images", description="Manage reference_images/.")
    refs_verbs = refs.add_subparsers(dest="refs_verb", metavar="ACTION", required=True)
    regen = refs_verbs.add_parser(
        "regenerate",
        help="re-render references (all, named, or --failed), then calibrate them",
        description="Render converged references in independent batches, refuse any that does not reproduce "
        "across seeds, print SSIM old vs new, write each file atomically, and recalibrate the thresholds.",
    )
    regen.add_argument("features", nargs="*", metavar="FEATURE")
    regen.add_argument("--failed", action="store_true", help="only features that fail (or lack a valid reference)")
    regen.add_argument("--spp", type=int, help="reference spp (default: the matrix entry's reference_spp)")
    regen.add_argument("--device", default="cpu")
    cal = refs_verbs.add_parser(
        "calibrate",
        help="set SSIM thresholds from renders with several seeds",
        description="Render each feature at its test spp with several seeds, record the spread of SSIM against the "
        "reference and set the threshold under it (min - max(0.002, 3 std)); stored in reference_images/NAME.json.",
    )
    cal.add_argument("features", nargs="*", metavar="FEATURE")
    cal.add_argument("--device", default="cpu")

    c = verbs.add_parser("compare", help="score two images", description="SSIM (tone-mapped), RMSE and max error (linear) of A against B.")
    c.add_argument("a", metavar="A", help="image to score (.exr or .png)")
    c.add_argument("b", metavar="B", help="reference image")
    c.add_argument("--threshold", type=float, help="exit 1 when SSIM is below this")

    rays = verbs.add_parser(
        "rays",
        help="show the rays traced for chosen pixels in 3D",
        description="Trace chosen pixels with the scene's integrator, recording every ray the render kernels trace "
        "(camera, shadow, reflected, refracted, totally internally reflected), and draw the ray trees with pyvista "
        "over the scene geometry, or export them as a VTK multiblock. See docs/rays.md.",
    )
    rays.add_argument("scene", help="scene file (.toml)")
    rays.add_argument("--pixel", nargs=2, type=int, action="append", default=[], metavar=("X", "Y"), help="a pixel to trace (row 0 at the top); repeatable")
    rays.add_argument("--grid", nargs=2, type=int, metavar=("NX", "NY"), help="also trace the centre pixels of an NX x NY grid over the image")
    rays.add_argument("--samples", type=int, default=1, help="samples per pixel (default 1: the pixel centre)")
    rays.add_argument("--depth", type=int, help="max_depth: ray segments per path, camera ray included (default: the scene's)")
    shown = rays.add_mutually_exclusive_group(required=True)
    shown.add_argument("-o", "--output", help="render the view off screen to this .png")
    shown.add_argument("--interactive", action="store_true", help="open a window (needs a display)")
    shown.add_argument("--export", help="write a VTK multiblock (.vtm) for ParaView or pyvista.read")
    rays.add_argument("--view", nargs=2, type=float, metavar=("AZIMUTH", "ELEVATION"), help="view angles in degrees relative to the scene camera (default: automatic)")
    rays.add_argument("--device", default="cpu", help="Warp device: cpu (default), cuda or cuda:N")
    rays.add_argument("--capacity", type=int, default=1 << 18, help="segments the record buffer holds (default 262144)")
    rays.add_argument("--show-bvh", action="store_true", help="also draw the BVH boxes each traced ray's closest-hit query visited")

    st = verbs.add_parser(
        "stress",
        help="run the numerical stress suite",
        description="Shoot adversarial rays through the real kernels (watertightness, self-intersection, sphere "
        "precision, float32 vs float64, grazing and degenerate geometry, refraction, NaN/Inf) and print a table: "
        "case, rays, failures, worst error, bound. Exit 0 when every case passes, 1 otherwise. See docs/stress.md.",
    )
    st.add_argument("--rays", type=int, default=10**6, help="rays per ray-batch case (default 1000000)")
    st.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    st.add_argument("--report", metavar="DIR", help="also write the table as DIR/stress.json and DIR/stress.md")

    b = verbs.add_parser(
        "bench",
        help="benchmark error against run time, per sampler, and against Mitsuba 3",
        description="Render each scene at a doubling series of spp (4, 8, ...) for each sampler (independent, "
        "stratified, sobol), adaptive sampling off and on, until each curve has used its time budget; measure wall "
        "time (after a warm-up render; compilation reported separately) and error against a converged reference "
        "(RMSE of linear values, 1-SSIM of tone-mapped sRGB); fit log-log slopes; for Mitsuba 3 XML scenes, compare "
        "with Mitsuba 3 at equal time; time the specialised against the all-features kernel on a diffuse-only "
        "scene. Writes DIR/results.json, results.csv and one log-log plot per scene; then measures ray throughput "
        "(DIR/throughput.json, see --triangles). See docs/performance.md.",
    )
    b.add_argument("scenes", nargs="*", metavar="SCENE", help="scene files, .toml or Mitsuba 3 .xml (default: the Cornell boxes and soft_shadows)")
    b.add_argument("--budget", type=float, metavar="SECONDS", help="render seconds per curve (default 6; 0.5 with --quick)")
    b.add_argument("-o", "--output", default="bench-results", metavar="DIR", help="output folder (default bench-results); references are cached in DIR/references")
    b.add_argument("--device", default="cpu", help="Warp device: cpu (default), cuda or cuda:N")
    b.add_argument("--quick", action="store_true", help="small images, 3 points per curve: a smoke test of the benchmark, not a measurement")
    b.add_argument(
        "--triangles",
        type=int,
        metavar="N",
        help="also measure ray throughput (rays/s of wrt's BVH, wp.Mesh and Embree when installed) on an N-triangle mesh: "
        "DIR/throughput.json (default 1000000; 20000 with --quick; 0 skips it)",
    )
    return parser


@contextlib.contextmanager
def _stop_on_ctrl_c():
    """Within: the first Ctrl-C (SIGINT) sets the event yielded instead of raising, a second one
    raises ``KeyboardInterrupt`` as usual."""
    stop = threading.Event()

    def first_ctrl_c(signum, frame):
        stop.set()
        signal.signal(signal.SIGINT, signal.default_int_handler)

    previous = signal.signal(signal.SIGINT, first_ctrl_c)
    try:
        yield stop
    finally:
        signal.signal(signal.SIGINT, previous)


def _render(args) -> int:
    from tqdm import tqdm

    from . import __version__
    from .device import init_warp
    from .imageio import write_image
    from .loader import load_scene, override_render
    from .renderer import render

    if args.threads is not None and args.threads < 1:
        raise WrtError(f"--threads {args.threads}: must be >= 1")
    if args.checkpoint_every is not None and args.checkpoint_every < 1:
        raise WrtError(f"--checkpoint-every {args.checkpoint_every}: must be >= 1")
    if args.target_error is not None and not args.target_error > 0.0:
        raise WrtError(f"--target-error {args.target_error}: must be > 0")
    ext = os.path.splitext(args.output)[1].lower()
    if ext not in (".exr", ".png"):
        raise WrtError(f"{args.output}: unsupported output format {ext or '(none)'!r} (use .exr or .png)")
    if args.aov and ext != ".exr":
        raise WrtError(f"{args.output}: --aov needs an .exr output")
    messages = init_warp()
    if args.device.startswith("cuda") and messages:
        print(messages, end="", file=sys.stderr)
    scene = override_render(load_scene(args.scene, strict=args.strict), width=args.width, height=args.height, spp=args.spp, seed=args.seed, sampler=args.sampler)
    pixels = scene.render.width * scene.render.height

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
    with bar, _stop_on_ctrl_c() as stop:

        def on_pass(done: int, spp: int, elapsed: float, snapshot) -> bool:
            if args.target_error is None:
                rate = done / max(elapsed, 1e-9)  # spp per second
                eta = tqdm.format_interval((spp - done) / rate)
                bar.set_postfix_str(f"{tqdm.format_interval(elapsed)}<{eta}, {rate * pixels / 1e6:.3g} M samples/s", refresh=False)
            else:  # fewer pixels each pass: no rate or ETA to promise
                bar.set_postfix_str(f"{tqdm.format_interval(elapsed)}, adaptive", refresh=False)
            bar.update(done - bar.n)
            if args.checkpoint_every and done % args.checkpoint_every == 0 and done < spp and not stop.is_set():
                write(snapshot())
            return not stop.is_set()

        result = render(
            scene, device=args.device, threads=args.threads, progress=on_pass, progress_every=args.checkpoint_every, target_error=args.target_error
        )
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
    if result.spp < scene.render.spp:
        print(f"wrt: interrupted: wrote the {result.spp} of {scene.render.spp} spp done", file=sys.stderr)
        return 130
    return 0


def _matrix(args) -> int:
    from harness import commands

    if args.jobs < 1:
        raise WrtError(f"--jobs {args.jobs}: must be >= 1")
    return commands.matrix(args.features, args.device, args.jobs, args.report)


def _refs(args) -> int:
    from harness import commands

    if args.refs_verb == "regenerate":
        if args.spp is not None and args.spp < 1:
            raise WrtError(f"--spp {args.spp}: must be >= 1")
        return commands.refs_regenerate(args.features, args.failed, args.spp, args.device)
    return commands.refs_calibrate(args.features, args.device)


def _compare(args) -> int:
    from harness import commands

    return commands.compare(args.a, args.b, args.threshold)


def _rays(args) -> int:
    from harness import rayview

    if not args.pixel and not args.grid:
        raise WrtError("give at least one --pixel X Y or a --grid NX NY")
    return rayview.run(
        args.scene, [tuple(p) for p in args.pixel], grid=args.grid, samples=args.samples, max_depth=args.depth, output=args.output,
        interactive=args.interactive, export_path=args.export, view=args.view, device=args.device, capacity=args.capacity,
        show_bvh=args.show_bvh,
    )


def _stress(args) -> int:
    from harness import stress

    if args.rays < 1:
        raise WrtError(f"--rays {args.rays}: must be >= 1")
    return stress.command(args.rays, args.seed, args.report)


def _bench(args) -> int:
    from harness import bench

    return bench.command(args.scenes, args.budget, args.output, args.device, args.quick, args.triangles)


VERBS = {"render": _render, "matrix": _matrix, "refs": _refs, "compare": _compare, "rays": _rays, "stress": _stress, "bench": _bench}


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.verb != "render":
            from .device import init_warp

            init_warp()
        return VERBS[args.verb](args)
    except WrtError as e:
        print(f"wrt: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("wrt: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
