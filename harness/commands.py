"""What the harness's verbs do (``wrt matrix``, ``wrt refs``, ``wrt compare``; their arguments are
parsed by ``wrt_harness.cli``). Each returns the process exit code: 0 all good, 1 a regression,
2 bad input (``WrtError``, raised to the CLI).

``features_file`` and ``refs`` (``--features FILE --refs DIR``) name a project's own feature list
and the folder of its references; None for wrt's own (``harness/features.toml`` and
``reference_images/``). A features file of one's own needs a folder of its own.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import time

from tqdm import tqdm

from wrt.errors import WrtError
from wrt.files import check_report_folder, check_writable, write_json
from wrt.host import machine_info
from wrt.imageio import read_image

from .false_alarms import false_alarms
from .flip import FLIP_CRITERION, check_flip_threshold, flip
from .matrix import FEATURES_FILE, Feature, load_features, select
from .references import (
    ReferenceError,
    calibrate,
    check_storable,
    load_reference,
    refs_command,
    render_reference,
    store,
    store_calibration,
)
from .run import evaluate, run_matrix
from .score import check_spp, check_threshold, image_problem, max_error, rmse, size_problem, ssim, z_test


def _table(results) -> str:
    lines = [f"{'feature':<28} {'SSIM vs ref':>20} {'SSIM vs geometry':>18} {'time':>8}  result"]
    for r in results:
        ref = f"{r.ssim:.4f} (>= {r.ssim_threshold:.4f})"
        geo = f"{r.geometry_ssim:.4f} (>= {r.feature.geometry_threshold:.2f})"
        lines.append(f"{r.feature.name:<28} {ref:>20} {geo:>18} {r.time_s:>7.2f}s  {'pass' if r.passed else 'FAIL'}")
        lines += [f"    {f}" for f in r.failures]
    return "\n".join(lines)


def _score(value) -> float | int | None:
    """A JSON-safe score: the number, or None for NaN or Inf."""
    return value if isinstance(value, int) or math.isfinite(value) else None


def _numbers(result, prefix: str = "") -> dict:
    """The numeric fields of the dataclass ``result`` by name, and those of the dataclasses in it
    but its feature (``z`` ``min_p`` as ``z_min_p``); None where not finite."""
    scores = {}
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            scores[prefix + f.name] = _score(value)
        elif dataclasses.is_dataclass(value) and not prefix and f.name != "feature":
            scores.update(_numbers(value, f"{f.name}_"))
    return scores


def matrix_json(results, wrong: bool = False) -> dict:
    """The matrix's results as data (``wrt matrix --json``): per feature name, ``passed``,
    ``failed_checks`` (names from ``run.CHECKS``, one per failure, in order), ``failures`` (their
    messages) and ``scores`` (the numeric fields of its ``FeatureResult`` and of its scores' own
    records: ``ssim``, ``z_min_p``, ``flip_hdr``, ``bias_max_z``...; the convergence slope; None
    where not finite)."""
    features = {}
    for r in results:
        scores = _numbers(r)
        if r.convergence is not None:
            scores["convergence_slope"] = _score(r.convergence["slope"])
            scores["convergence_z_min_p"] = _score(r.convergence["z"].min_p)
        features[r.feature.name] = {
            "passed": bool(r.passed),
            "failed_checks": list(r.failed_checks),
            "failures": list(r.failures),
            "scores": scores,
        }
    return {"wrong": wrong, "features": features}


def _features(names: list[str], features_file: str | None, refs: str | None, made: bool = True) -> list[Feature]:
    """The features called ``names`` (all when empty) of ``features_file``; ``WrtError`` when a
    features file comes without ``refs``, or (``made``) when the folder ``refs`` does not exist."""
    features = select(load_features(features_file or FEATURES_FILE), names)
    if features_file is not None and refs is None:
        raise WrtError(f"--features {features_file}: name the folder of its references with --refs DIR")
    if made and refs is not None and not os.path.isdir(refs):
        make = refs_command("regenerate", features_file, refs)
        raise WrtError(f"--refs {refs}: no such folder; make its references with: {make}")
    return features


def coverage_table(names: list[str], features_file: str | None = None) -> int:
    """Print which of the features called ``names`` (all when empty) of ``features_file`` (None:
    wrt's own) exercise each kind of the scene format (``coverage.coverage``), rendering nothing;
    exit 1 when a kind has no feature."""
    from .coverage import coverage, empty, format_table

    rows = coverage(select(load_features(features_file or FEATURES_FILE), names))
    print(format_table(rows))
    return 1 if empty(rows) else 0


def matrix(
    names: list[str],
    device: str,
    jobs: int,
    report: str | None,
    features_file: str | None = None,
    refs: str | None = None,
    wrong: bool = False,
    cluster=None,
    json_path: str | None = None,
) -> int:
    """Run the matrix (with ``wrong``: render the wrong variants, each of which must fail); on
    ``cluster`` (a ``wrt.distributed.Cluster``), one task per feature; with ``json_path``, write
    the results there too (``matrix_json``)."""
    features = _features(names, features_file, refs)
    if json_path:  # every output is checked before the renders
        check_writable(json_path, option="--json", protect=(features_file or FEATURES_FILE,))
    if report:
        check_report_folder(report)
    if wrong:
        missing = [f for f in features if not f.wrong]
        if missing:
            raise WrtError(f"{missing[0].features_file}: feature {missing[0].name!r} has no wrong variant (key wrong)")
    start = time.perf_counter()
    with tqdm(total=len(features), desc="wrt matrix", unit="feature", file=sys.stderr, disable=None) as bar:

        def progress(result):
            bar.set_postfix_str(f"{result.feature.name}: {'pass' if result.passed else 'FAIL'}")
            bar.update(1)

        results = run_matrix(
            features, device=device, jobs=jobs, progress=progress, refs=refs, wrong=wrong, cluster=cluster
        )
    elapsed = time.perf_counter() - start
    if wrong:
        print("wrong variants: each must FAIL")
    print(_table(results))
    failed = [r.feature.name for r in results if not r.passed]
    if json_path:
        write_json(json_path, matrix_json(results, wrong))
        print(f"results: {json_path}")
    if report:
        from .report import write_report

        print(f"report: {write_report(results, report, device, total_s=elapsed)}")
    if wrong:
        missed = [r.feature.name for r in results if r.passed]
        print(
            f"{len(failed)} wrong variants caught, {len(missed)} missed" + (f": {', '.join(missed)}" if missed else "")
        )
        return 1 if missed else 0
    print(f"{len(results) - len(failed)} passed, {len(failed)} failed")
    return 1 if failed else 0


def refs_regenerate(
    names: list[str],
    failed_only: bool,
    spp: int | None,
    device: str,
    features_file: str | None = None,
    refs: str | None = None,
    cluster=None,
) -> int:
    """Re-render and calibrate references; the folder ``refs`` is made if missing. On ``cluster``
    (a ``wrt.distributed.Cluster``), one task per reference batch, calibration render and
    (``--failed``) feature."""
    features = _features(names, features_file, refs, made=False)
    if refs is not None:
        try:
            os.makedirs(refs, exist_ok=True)
        except OSError as e:
            raise WrtError(f"--refs {refs}: cannot make the folder ({e.strerror})") from None
    check_storable(features, refs)  # before any render: a read-only folder, a folder in a file's place
    if failed_only:
        todo = []
        for feature in features:
            try:
                if not evaluate(feature, device=device, refs=refs, cluster=cluster).passed:
                    todo.append(feature)
            except ReferenceError:
                todo.append(feature)
        features = todo
    for feature in features:
        try:
            old = load_reference(feature, refs, calibration=False)
        except ReferenceError:
            old = None
        new = render_reference(feature, spp=spp, device=device, cluster=cluster)
        change = (
            "new reference"
            if old is None or old.rgb.shape != new.rgb.shape
            else f"SSIM old vs new {ssim(new.rgb, old.rgb):.4f}, RMSE {rmse(new.rgb, old.rgb):.2e}"
        )
        store(feature, new, refs)
        stored = load_reference(feature, refs, calibration=False)
        cal = calibrate(feature, stored, device=device, cluster=cluster)
        store_calibration(feature, cal, refs)
        print(f"{feature.name}: {new.spp} spp, {change}; SSIM threshold {cal['ssim_threshold']:.4f} (calibrated)")
    if not features:
        print("nothing to regenerate")
    return 0


def refs_false_alarms(
    names: list[str],
    count: int,
    max_rate: float,
    json_path: str | None,
    device: str,
    features_file: str | None = None,
    refs: str | None = None,
) -> int:
    """Measure the false-alarm rate of each stochastic feature over ``count`` seeds
    (``false_alarms.false_alarms``); exit 1 when one exceeds ``max_rate``."""
    features = [f for f in _features(names, features_file, refs) if f.stochastic]
    if json_path:
        check_writable(json_path, option="--json", protect=(features_file or FEATURES_FILE,))
    results = []
    for feature in features:
        with tqdm(total=count, desc=feature.name, unit="seed", file=sys.stderr, disable=None) as bar:
            r = false_alarms(feature, count, refs, device, log=lambda seed, result: bar.update(1))
        checks = ", ".join(f"{check} {n}" for check, n in sorted(r["by_check"].items())) or "none"
        print(f"{feature.name}: {r['failing_seeds']} of {count} seeds fail ({r['rate']:.1%}); by check: {checks}")
        results.append(r)
    if not features:
        print("no stochastic feature to measure")
    if json_path:
        write_json(json_path, {"machine": machine_info(), "device": device, "max_rate": max_rate, "features": results})
    over = [r["feature"] for r in results if r["rate"] > max_rate]
    if over:
        print(f"{len(over)} features above a false-alarm rate of {max_rate:.1%}: {', '.join(over)}")
    return 1 if over else 0


def refs_calibrate(names: list[str], device: str, features_file: str | None = None, refs: str | None = None) -> int:
    """Calibrate the stored references of the features called ``names`` (all when empty) again."""
    features = _features(names, features_file, refs)
    check_storable(features, refs, ("json",))
    for feature in features:
        cal = calibrate(feature, load_reference(feature, refs, calibration=False), device=device)
        store_calibration(feature, cal, refs)
        flips = cal[f"{cal['flip_criterion']}_flip"]
        print(
            f"{feature.name}: SSIM {min(cal['ssim']):.4f}..{max(cal['ssim']):.4f} over seeds {cal['seeds']}, "
            f"threshold {cal['ssim_threshold']:.4f}; {cal['flip_criterion'].upper()}-FLIP "
            f"{min(flips):.4f}..{max(flips):.4f}, threshold {cal['flip_threshold']:.4f}"
        )
    return 0


def compare(a: str, b: str, threshold: float | None, metric: str = "ssim") -> int:
    """Score image ``a`` against ``b`` by ``metric``: "ssim" (exit 1 when SSIM < ``threshold``) or
    "flip" (HDR- and LDR-FLIP; exit 1 when the pass criterion's FLIP, ``flip.FLIP_CRITERION``, >
    ``threshold``); exit 1 as well when the Z-test runs (``b`` has a variance, both a ``wrt:spp``)
    and fails. Refused (``WrtError``): a threshold that is not a finite number in [-1, 1]
    (SSIM) or >= 0 (FLIP), an image with NaN or Inf values or a negative variance, smaller than the
    SSIM window (SSIM), of another size than the other, or with a ``wrt:spp`` that is not a whole
    number >= 1."""
    if threshold is not None:
        check = check_flip_threshold if metric == "flip" else check_threshold
        threshold = check(threshold, "--threshold")
    image, reference = read_image(a), read_image(b)
    for path, data in ((a, image), (b, reference)):
        problem = image_problem(data.rgb, data.aovs.get("variance"))
        if problem:
            raise WrtError(f"{path}: cannot be scored: {problem}")
        problem = size_problem(data.rgb.shape) if metric == "ssim" else None
        if problem:
            raise WrtError(f"{path} {problem}")
    if image.rgb.shape != reference.rgb.shape:
        raise WrtError(
            f"{a} is {image.rgb.shape[1]}x{image.rgb.shape[0]} but {b} is "
            f"{reference.rgb.shape[1]}x{reference.rgb.shape[0]}"
        )
    if metric == "flip":
        scores = flip(image.rgb, reference.rgb)
        print(f"HDR-FLIP {scores.hdr:.6f} (linear RGB)")
        print(f"LDR-FLIP {scores.ldr:.6f} (tone-mapped sRGB)")
    else:
        score = ssim(image.rgb, reference.rgb)
        print(f"SSIM {score:.6f} (tone-mapped sRGB, data_range 1)")
    print(f"RMSE {rmse(image.rgb, reference.rgb):.6e}  max error {max_error(image.rgb, reference.rgb):.6e} (linear)")
    z = None
    if "variance" in reference.aovs and "spp" in image.metadata and "spp" in reference.metadata:
        z = z_test(
            image.rgb,
            check_spp(image.metadata["spp"], f"{a}: wrt:spp"),
            reference.rgb,
            reference.aovs["variance"],
            check_spp(reference.metadata["spp"], f"{b}: wrt:spp"),
        )
        print(
            f"Z-test {'pass' if z.passed else 'FAIL'}: min p {z.min_p:.3e}, level {z.threshold:.3e}, {z.rejected} "
            "rejected"
        )
    failed = z is not None and not z.passed
    if threshold is not None and metric == "flip" and not scores.criterion <= threshold:
        print(f"FAIL: {FLIP_CRITERION.upper()}-FLIP {scores.criterion:.6f} > {threshold}")
        failed = True
    elif threshold is not None and metric == "ssim" and not score >= threshold:
        print(f"FAIL: SSIM {score:.6f} < {threshold}")
        failed = True
    return 1 if failed else 0
