"""The harness's command-line verbs: ``wrt matrix``, ``wrt refs``, ``wrt compare`` and ``wrt mutants``.

``wrt`` finds them through the ``wrt.commands`` entry points of this package (pyproject.toml):
each entry point (``matrix_verb`` ...) adds its subparser to ``wrt``'s and returns the function
that runs it, so ``wrt`` never imports the harness, and this module imports nothing heavy: the
work is in ``wrt_harness.commands``, imported when a verb runs. The harness's own command,
``wrt-harness VERB`` (or ``python -m wrt_harness VERB``), runs the same verbs without ``wrt``.
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Callable

from wrt.cli import add_device_option
from wrt.errors import WrtError

Run = Callable[[argparse.Namespace], int]


def add_matrix_options(parser: argparse.ArgumentParser) -> None:
    """``--features FILE --refs DIR``: a project's own feature list and references folder."""
    parser.add_argument(
        "--features",
        dest="features_file",
        metavar="FILE",
        help="the feature list (default: wrt's own); its scene paths are relative to its folder; needs --refs",
    )
    parser.add_argument("--refs", metavar="DIR", help="the folder of its reference images (default: wrt's own)")


def add_scheduler_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--scheduler ADDRESS``: run on a Dask distributed cluster (``wrt.distributed``)."""
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help=f"run on the Dask distributed cluster whose scheduler is at ADDRESS (tcp://host:8786), one task per "
        f"{what}: the same results (needs the cluster extra; see docs/cluster.md)",
    )


def _cluster(scheduler: str | None):
    """The ``wrt.distributed.Cluster`` at ``scheduler`` (a context), or for None a null one: run here."""
    if scheduler is None:
        return contextlib.nullcontext()
    from wrt.distributed import Cluster

    return Cluster(scheduler)


def matrix_verb(verbs) -> Run:
    """``wrt matrix [FEATURE...] [--device] [--jobs N] [--report DIR] [--wrong] [--features FILE --refs DIR]``,
    ``wrt matrix --coverage [FEATURE...] [--features FILE]``."""
    m = verbs.add_parser(
        "matrix",
        help="run the feature test matrix (visual regression harness)",
        description="Render every feature of the feature list (or those named), score it by SSIM and a per-pixel "
        "Z-test against its reference and by SSIM of its object ids against a pyvista rasterisation, check "
        "convergence, print a table. Exit 0 when all pass, 1 on a regression, 2 on bad input.",
    )
    m.add_argument("features", nargs="*", metavar="FEATURE", help="feature names (default: all)")
    add_device_option(m)
    m.add_argument("--jobs", type=int, default=1, help="features rendered at once (default 1; each uses all cores)")
    m.add_argument("--report", metavar="DIR", help="write an HTML report (DIR/index.html and PNGs)")
    m.add_argument(
        "--wrong", action="store_true", help="render the wrong variants instead; exit 1 when one of them passes"
    )
    m.add_argument(
        "--json",
        metavar="FILE",
        help="also write the results to FILE (atomically): per feature, passed, failed_checks and scores",
    )
    m.add_argument(
        "--coverage",
        action="store_true",
        help="render nothing: list every kind of the scene format (camera types, shapes, materials, lights, "
        "samplers...) with the features that exercise it; exit 1 when a kind has none",
    )
    add_matrix_options(m)
    add_scheduler_option(m, "feature")

    def run(args: argparse.Namespace) -> int:
        if args.coverage:
            options = {
                "--wrong": args.wrong,
                "--report": args.report,
                "--json": args.json,
                "--scheduler": args.scheduler,
            }
            given = [option for option, value in options.items() if value]
            if given:
                raise WrtError(f"{given[0]}: not with --coverage (it renders nothing)")
            from .commands import coverage_table

            return coverage_table(args.features, args.features_file)
        if args.jobs < 1:
            raise WrtError(f"--jobs {args.jobs}: must be >= 1")
        if args.jobs > 1 and args.scheduler is not None:
            raise WrtError(f"--jobs {args.jobs}: not with --scheduler (the cluster runs a feature per worker thread)")
        from .commands import matrix

        with _cluster(args.scheduler) as cluster:
            return matrix(
                args.features,
                args.device,
                args.jobs,
                args.report,
                args.features_file,
                args.refs,
                args.wrong,
                cluster=cluster,
                json_path=args.json,
            )

    return run


def refs_verb(verbs) -> Run:
    """``wrt refs regenerate|calibrate|false-alarms [FEATURE...] [--features FILE --refs DIR]``."""
    refs = verbs.add_parser(
        "refs", help="regenerate or calibrate reference images", description="Manage the matrix's reference images."
    )
    actions = refs.add_subparsers(dest="refs_verb", metavar="ACTION", required=True)
    regen = actions.add_parser(
        "regenerate",
        help="re-render references (all, named, or --failed), then calibrate them",
        description="Render converged references in independent batches, refuse any that does not reproduce "
        "across seeds, print SSIM old vs new, write each file atomically, and recalibrate the thresholds.",
    )
    regen.add_argument("features", nargs="*", metavar="FEATURE")
    regen.add_argument("--failed", action="store_true", help="only features that fail (or lack a valid reference)")
    regen.add_argument("--spp", type=int, help="reference spp (default: the matrix entry's reference_spp)")
    add_device_option(regen)
    add_matrix_options(regen)
    add_scheduler_option(regen, "reference batch and calibration render")
    cal = actions.add_parser(
        "calibrate",
        help="set SSIM thresholds from renders with several seeds",
        description="Render each feature at its test spp with several seeds, record the spread of SSIM against the "
        "reference and set the threshold under it (min - max(0.002, 3 std)); stored beside the reference as NAME.json.",
    )
    cal.add_argument("features", nargs="*", metavar="FEATURE")
    add_device_option(cal)
    add_matrix_options(cal)
    fa = actions.add_parser(
        "false-alarms",
        help="measure how often stochastic features fail on sound code",
        description="Score each stochastic feature (all, or those named) with every check of the matrix at SEEDS "
        "other seeds against its reference, and count the seeds at which it fails, per check and in all: the "
        "false-alarm rate a developer sees. Exit 1 when a rate exceeds --max-rate.",
    )
    fa.add_argument("features", nargs="*", metavar="FEATURE")
    fa.add_argument("--seeds", type=int, default=50, help="seeds per feature (default 50)")
    fa.add_argument("--max-rate", type=float, default=0.01, help="largest acceptable rate (default 0.01)")
    fa.add_argument("--json", metavar="FILE", help="also write the counts and failures to FILE (atomically)")
    add_device_option(fa)
    add_matrix_options(fa)

    def run(args: argparse.Namespace) -> int:
        from .commands import refs_calibrate, refs_false_alarms, refs_regenerate

        if args.refs_verb == "false-alarms":
            if args.seeds < 1:
                raise WrtError(f"--seeds {args.seeds}: must be >= 1")
            if not 0.0 <= args.max_rate <= 1.0:  # NaN fails too
                raise WrtError(f"--max-rate {args.max_rate}: must be in [0, 1]")
            return refs_false_alarms(
                args.features, args.seeds, args.max_rate, args.json, args.device, args.features_file, args.refs
            )

        if args.refs_verb == "regenerate":
            if args.spp is not None and args.spp < 1:
                raise WrtError(f"--spp {args.spp}: must be >= 1")
            with _cluster(args.scheduler) as cluster:
                return refs_regenerate(
                    args.features, args.failed, args.spp, args.device, args.features_file, args.refs, cluster=cluster
                )
        return refs_calibrate(args.features, args.device, args.features_file, args.refs)

    return run


def compare_verb(verbs) -> Run:
    """``wrt compare A B [--metric ssim|flip] [--threshold T]``."""
    c = verbs.add_parser(
        "compare",
        help="score two images",
        description="SSIM (tone-mapped) or FLIP (HDR and LDR), RMSE and max error (linear) of A against B.",
    )
    c.add_argument("a", metavar="A", help="image to score (.exr or .png)")
    c.add_argument("b", metavar="B", help="reference image")
    c.add_argument(
        "--metric",
        choices=("ssim", "flip"),
        default="ssim",
        help="ssim (default), or flip: NVIDIA's FLIP, HDR on the linear values and LDR on the tone-mapped ones",
    )
    c.add_argument(
        "--threshold", type=float, help="exit 1 when SSIM is below this (--metric flip: when HDR-FLIP is above it)"
    )

    def run(args: argparse.Namespace) -> int:
        from .commands import compare

        return compare(args.a, args.b, args.threshold, args.metric)

    return run


def mutants_verb(verbs) -> Run:
    """``wrt mutants [FAULT...] [--report DIR] [--jobs N] [--expected | --first-catch] [--faults FILE]
    [--kernel-cache DIR] [--features FILE --refs DIR]``."""
    m = verbs.add_parser(
        "mutants",
        help="plant renderer faults one at a time and count those the matrix catches",
        description="For each planted fault of the faults file (all, or those named): copy the installed wrt and "
        "wrt_harness to a scratch folder, apply the fault's code change there (never in the working tree), run "
        "the matrix on the copy, and report which features failed and by which check; last, the line "
        "'K of N planted faults caught'. Results go to DIR/mutants.json; a fault already measured there for the "
        "same fault and source tree is not run again. Exit 0 when all are caught, 1 when one survives, 2 on bad "
        "input. See docs/harness.md.",
    )
    m.add_argument("faults", nargs="*", metavar="FAULT", help="fault ids (default: all)")
    m.add_argument("--report", metavar="DIR", default="mutants", help="results folder (default: ./mutants)")
    m.add_argument("--faults", dest="faults_file", metavar="FILE", help="the faults file (default: wrt's own)")
    m.add_argument("--jobs", type=int, default=1, help="passed to wrt matrix (features rendered at once)")
    quick = m.add_mutually_exclusive_group()
    quick.add_argument(
        "--expected",
        dest="mode",
        action="store_const",
        const="expected",
        default="full",
        help="run only each fault's expected features (not the whole matrix)",
    )
    quick.add_argument(
        "--first-catch",
        dest="mode",
        action="store_const",
        const="first-catch",
        help="quick mode: run each fault's expected features one at a time, then the rest of the matrix, and stop "
        "at the first run that catches it; no per-check counts",
    )
    m.add_argument(
        "--kernel-cache",
        metavar="DIR",
        help="Warp kernel cache of the mutant runs (default: Warp's own, where the unmutated kernels are cached)",
    )
    add_device_option(m)
    add_matrix_options(m)

    def run(args: argparse.Namespace) -> int:
        if args.jobs < 1:
            raise WrtError(f"--jobs {args.jobs}: must be >= 1")
        from .mutants import mutants

        return mutants(
            args.faults,
            args.report,
            faults_file=args.faults_file,
            jobs=args.jobs,
            mode=args.mode,
            kernel_cache=args.kernel_cache,
            device=args.device,
            features_file=args.features_file,
            refs=args.refs,
        )

    return run


def main(argv: list[str] | None = None) -> int:
    """``wrt-harness matrix|refs|compare ...``: the harness's verbs as a command of its own."""
    from wrt.cli import Parser, run_verb

    parser = Parser(
        prog="wrt-harness", description="wrt's visual regression harness (the same verbs as wrt matrix, refs, compare)"
    )
    verbs = parser.add_subparsers(dest="verb", required=True, metavar="VERB")
    runs = {
        "matrix": matrix_verb(verbs),
        "refs": refs_verb(verbs),
        "compare": compare_verb(verbs),
        "mutants": mutants_verb(verbs),
    }
    args = parser.parse_args(argv)
    return run_verb(runs[args.verb], args, prog="wrt-harness")
