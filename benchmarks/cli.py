"""``wrt bench``, a ``wrt.commands`` entry point (see ``wrt_harness.cli``): its arguments here, the
work in ``wrt_benchmarks.bench``, imported when the verb runs."""

from __future__ import annotations

import argparse
from collections.abc import Callable

from wrt.cli import add_device_option


def bench_verb(verbs) -> Callable[[argparse.Namespace], int]:
    """``wrt bench [SCENE...] [--budget S] [-o DIR] [--device] [--quick] [--triangles N]``."""
    b = verbs.add_parser(
        "bench",
        help="benchmark error against run time, per sampler, and against Mitsuba 3",
        description="Render each scene at a doubling series of spp (4, 8, ...) for each sampler (independent, "
        "stratified, sobol), adaptive sampling off and on, until each curve has used its time budget; measure wall "
        "time (after a warm-up render; compilation reported separately) and error against a converged reference "
        "(RMSE of linear values, 1-SSIM of tone-mapped sRGB); fit log-log slopes; for Mitsuba 3 XML scenes, compare "
        "with Mitsuba 3 at equal time; time the specialised against the all-features kernel on a diffuse-only "
        "scene. Writes DIR/results.json, results.csv and one log-log plot per scene; then measures ray throughput "
        "(DIR/throughput.json, see --triangles), BVH build times and whole processes against Mitsuba 3, and writes "
        "every ratio beside its target (DIR/targets.json). See docs/performance.md.",
    )
    b.add_argument(
        "scenes",
        nargs="*",
        metavar="SCENE",
        help="scene files, .toml or Mitsuba 3 .xml (default: the Cornell boxes and soft_shadows)",
    )
    b.add_argument(
        "--budget", type=float, metavar="SECONDS", help="render seconds per curve (default 6; 0.5 with --quick)"
    )
    b.add_argument(
        "-o",
        "--output",
        default="bench-results",
        metavar="DIR",
        help="output folder (default bench-results); references are cached in DIR/references",
    )
    add_device_option(b)
    b.add_argument(
        "--quick",
        action="store_true",
        help="small images, 3 points per curve: a smoke test of the benchmark, not a measurement",
    )
    b.add_argument(
        "--triangles",
        type=int,
        metavar="N",
        help="also measure ray throughput (rays/s of wrt's BVH, wp.Mesh and Embree when installed) on an N-triangle "
        "mesh, build times and whole processes: DIR/throughput.json and DIR/targets.json (default 1000000; 20000 "
        "with --quick; 0 skips them)",
    )

    def run(args: argparse.Namespace) -> int:
        from .bench import command

        return command(args.scenes, args.budget, args.output, args.device, args.quick, args.triangles)

    return run
