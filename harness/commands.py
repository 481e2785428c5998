"""What the harness's verbs do (``wrt matrix``, ``wrt refs``, ``wrt compare``; their arguments are
parsed by ``wrt_harness.cli``). Each returns the process exit code: 0 all good, 1 a regression,
2 bad input (``WrtError``, raised to the CLI)."""

from __future__ import annotations

import sys

from tqdm import tqdm

from wrt.errors import WrtError
from wrt.imageio import read_image

from .matrix import load_features, select
from .references import (
    ReferenceError,
    calibrate,
    load_reference,
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


def matrix(names: list[str], device: str, jobs: int, report: str | None) -> int:
    features = select(load_features(), names)
    with tqdm(total=len(features), desc="wrt matrix", unit="feature", file=sys.stderr, disable=None) as bar:

        def progress(result):
            bar.set_postfix_str(f"{result.feature.name}: {'pass' if result.passed else 'FAIL'}")
            bar.update(1)

        results = run_matrix(features, device=device, jobs=jobs, progress=progress)
    print(_table(results))
    failed = [r.feature.name for r in results if not r.passed]
    if report:
        from .report import write_report

        print(f"report: {write_report(results, report, device)}")
    print(f"{len(results) - len(failed)} passed, {len(failed)} failed")
    return 1 if failed else 0


def refs_regenerate(names: list[str], failed_only: bool, spp: int | None, device: str) -> int:
    features = select(load_features(), names)
    if failed_only:
        todo = []
        for feature in features:
            try:
                if not evaluate(feature, device=device).passed:
                    todo.append(feature)
            except ReferenceError:
                todo.append(feature)
        features = todo
    for feature in features:
        try:
            old = load_reference(feature, calibration=False)
        except ReferenceError:
            old = None
        new = render_reference(feature, spp=spp, device=device)
        change = (
            "new reference"
            if old is None or old.rgb.shape != new.rgb.shape
            else f"SSIM old vs new {ssim(new.rgb, old.rgb):.4f}, RMSE {rmse(new.rgb, old.rgb):.2e}"
        )
        store(feature, new)
        stored = load_reference(feature, calibration=False)
        cal = calibrate(feature, stored, device=device)
        store_calibration(feature, cal)
        print(f"{feature.name}: {new.spp} spp, {change}; SSIM threshold {cal['ssim_threshold']:.4f} (calibrated)")
    if not features:
        print("nothing to regenerate")
    return 0


def refs_calibrate(names: list[str], device: str) -> int:
    for feature in select(load_features(), names):
        cal = calibrate(feature, load_reference(feature, calibration=False), device=device)
        store_calibration(feature, cal)
        print(
            f"{feature.name}: SSIM {min(cal['ssim']):.4f}..{max(cal['ssim']):.4f} over seeds {cal['seeds']}, "
            f"threshold {cal['ssim_threshold']:.4f}"
        )
    return 0


def compare(a: str, b: str, threshold: float | None) -> int:
    """Score image ``a`` against ``b``. Refused (``WrtError``): a threshold outside [-1, 1] or NaN,
    an image with NaN or Inf values or a negative variance, smaller than the SSIM window, of
    another size than the other, or with a ``wrt:spp`` that is not a whole number >= 1."""
    if threshold is not None:
        threshold = check_threshold(threshold, "--threshold")
    image, reference = read_image(a), read_image(b)
    for path, data in ((a, image), (b, reference)):
        problem = image_problem(data.rgb, data.aovs.get("variance"))
        if problem:
            raise WrtError(f"{path}: cannot be scored: {problem}")
        problem = size_problem(data.rgb.shape)
        if problem:
            raise WrtError(f"{path} {problem}")
    if image.rgb.shape != reference.rgb.shape:
        raise WrtError(
            f"{a} is {image.rgb.shape[1]}x{image.rgb.shape[0]} but {b} is "
            f"{reference.rgb.shape[1]}x{reference.rgb.shape[0]}"
        )
    score = ssim(image.rgb, reference.rgb)
    print(f"SSIM {score:.6f} (tone-mapped sRGB, data_range 1)")
    print(f"RMSE {rmse(image.rgb, reference.rgb):.6e}  max error {max_error(image.rgb, reference.rgb):.6e} (linear)")
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
    if threshold is not None and not score >= threshold:
        print(f"FAIL: SSIM {score:.6f} < {threshold}")
        return 1
    return 0
