"""Running the matrix: render each feature, score it against its reference and its geometry
oracle, tell noise from regressions, check convergence.

A feature passes when all hold:
- SSIM against the reference >= its calibrated threshold, HDR-FLIP (``flip.py``) <= its
  calibrated threshold, and the per-pixel Z-test passes (a stochastic feature that misses any is
  re-rendered once at 4x spp and scored as both renders pooled: noise goes away, a real
  regression stays);
- SSIM of the ``object_id`` AOV against pyvista's rasterisation >= the geometry threshold;
- stochastic features: three more renders at N, 4N and 16N spp (independent seeds) pooled into
  one of 21N spp converge to the reference: the per-pixel Z-test passes at 21N spp, where a wrong
  converged image has nowhere to hide (the RMSE slope over N, 4N, 16N is reported, not judged:
  fireflies make it flatten on sound code, see docs/harness.md);
- stochastic features: the pooled render's means over the image and over a grid of large
  regions are the reference's within their noise (``score.bias_test``): a global bias of 1%
  hides in per-pixel noise, not in a mean of millions of samples;
- features with a ``closed_form_mean``: the image mean of every render made (pooled) is that
  exact value within its noise (``closed_form.py``), wrong variants included;
- the render is finite: a NaN or Inf pixel fails the feature (it is never scored as black);
- features rendered in several passes (``passes``): the image is bit-identical to the one-pass
  render of the same spp and seed. Adaptive features (``target_error``) are scored with each
  pixel's own sample count, and each pixel is bit for bit the pixel of a plain render of the
  samples its ``spp`` AOV says it took.
Every comparison is written so that a NaN score fails.
"""

from __future__ import annotations

import os
import time
import traceback
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from wrt.errors import WrtError
from wrt.renderer import ADAPTIVE_FIRST_PASS

from .closed_form import closed_form_failure
from .flip import FLIP_CRITERION, Flip, flip
from .matrix import Feature, load_feature_scene
from .oracle import palette, rasterize_ids
from .references import (
    RERENDER_SEED_OFFSET,
    RERENDER_SPP,
    ReferenceError,
    load_reference,
    render_feature,
    samples,
)
from .score import (
    BiasTest,
    ZTest,
    batch_variance,
    bias_test,
    convergence_slope,
    image_problem,
    max_error,
    pooled,
    rmse,
    ssim,
    z_test,
)

# the checks a feature can fail, by the names reports and `wrt mutants` count them under
CHECKS = (
    "finite",
    "ssim",
    "flip",
    "z",
    "bias",
    "closed_form",
    "geometry",
    "convergence",
    "progressive",
    "adaptive",
    "crash",
)


@dataclass
class FeatureResult:
    feature: Feature
    passed: bool
    ssim: float = float("nan")
    ssim_threshold: float = float("nan")
    flip: Flip | None = None  # HDR- and LDR-FLIP; None for a render with NaN or Inf values
    flip_threshold: float = float("nan")  # of flip.FLIP_CRITERION, from the calibration
    z: ZTest | None = None
    geometry_ssim: float = float("nan")
    rmse: float = float("nan")
    max_error: float = float("nan")
    time_s: float = 0.0
    rerendered: bool = False
    convergence: dict | None = None
    bias: BiasTest | None = None  # stochastic features: region means of the pooled convergence renders
    failures: list[str] = field(default_factory=list)
    failed_checks: list[str] = field(default_factory=list)  # CHECKS, one per failure, in order
    images: dict = field(default_factory=dict)  # linear RGB / id images for the report

    def fail(self, check: str, message: str) -> None:
        """Record a failure of ``check`` (one of ``CHECKS``) with its one-line ``message``."""
        assert check in CHECKS, check
        self.failures.append(message)
        self.failed_checks.append(check)


def score_render(
    feature: Feature,
    rgb: np.ndarray,
    spp: int,
    reference,
    threshold: float,
    flip_threshold: float,
    variance: np.ndarray | None = None,
) -> tuple[float, Flip | None, ZTest, bool]:
    """SSIM and FLIP (NaN and None for a render with NaN or Inf values, which fails), the Z-test
    (per-sample ``variance``, default the reference's), and whether all three pass."""
    clean = not image_problem(rgb)
    s = ssim(rgb, reference.rgb) if clean else float("nan")
    f = flip(rgb, reference.rgb) if clean else None
    z = z_test(rgb, spp, reference.rgb, reference.variance if variance is None else variance, reference.spp)
    return s, f, z, s >= threshold and f is not None and f.criterion <= flip_threshold and z.passed


def evaluate(
    feature: Feature,
    device: str = "cpu",
    threads: int | None = None,
    wrong: bool = False,
    refs: str | None = None,
    cluster=None,
) -> FeatureResult:
    """Render and score one feature (or its deliberately wrong variant) against its reference in
    the folder ``refs`` (default: wrt's own, ``references.REFERENCE_DIR``) and its geometry oracle.
    On ``cluster`` (a ``wrt.distributed.Cluster``) the renders and the scores against the
    reference are one task (``score_against_reference``: the parsed scene and the reference travel
    with it); the geometry oracle runs here.

    Raises ``ReferenceError`` when the reference is missing, stale or not calibrated.
    """
    reference = load_reference(feature, refs)
    if reference.calibration is None:
        raise ReferenceError(feature, "it has no calibration", "calibrate", refs)
    scene = load_feature_scene(feature, wrong)
    if cluster is None:
        out = score_against_reference(feature, scene, reference, device, threads, wrong)
    else:
        out = cluster.submit(score_against_reference, feature, scene, reference, device, 1, wrong).result()
    ids = rasterize_ids(scene)
    check_geometry(out, ids)
    out.passed = not out.failures
    out.images["raster_ids"] = ids
    return out


def check_geometry(out: FeatureResult, raster_ids: np.ndarray) -> None:
    """Score the render's ``object_id`` AOV against the rasterised ids, by SSIM of their palettes."""
    out.geometry_ssim = ssim(palette(out.images["ids"]), palette(raster_ids))
    if not out.geometry_ssim >= out.feature.geometry_threshold:
        out.fail("geometry", f"geometry SSIM {out.geometry_ssim:.4f} < {out.feature.geometry_threshold}")


def score_against_reference(
    feature: Feature, scene, reference, device: str = "cpu", threads: int | None = None, wrong: bool = False
) -> FeatureResult:
    """The part of ``evaluate`` that renders: render ``scene`` (the feature's, or its wrong
    variant's), score it against ``reference``, re-render a stochastic miss at 4x spp, check
    convergence. ``images["ids"]``: the first render's ``object_id`` AOV, for the geometry oracle."""
    threshold, flip_threshold = reference.calibration["ssim_threshold"], reference.calibration["flip_threshold"]
    start = time.perf_counter()
    result = render_feature(feature, device=device, threads=threads, scene=scene)
    elapsed = time.perf_counter() - start
    out = FeatureResult(
        feature=feature, passed=False, ssim_threshold=threshold, flip_threshold=flip_threshold, time_s=elapsed
    )
    out.ssim, out.flip, out.z, ok = score_render(
        feature, result.rgb, samples(result), reference, threshold, flip_threshold
    )
    if feature.target_error is not None:
        adaptive_failure(out, feature, result, scene, device, threads)
    if feature.passes > 1:  # passes do not change the image: bit for bit the one-pass render
        one = render_feature(feature, device=device, threads=threads, scene=scene, as_tested=False)
        if not np.array_equal(result.rgb, one.rgb):
            differ = int(np.count_nonzero(np.any(result.rgb != one.rgb, axis=-1)))
            out.fail(
                "progressive",
                f"the render in {feature.passes} passes differs from the one-pass render in {differ} pixels",
            )
    out.rmse, out.max_error = rmse(result.rgb, reference.rgb), max_error(result.rgb, reference.rgb)
    rgb = result.rgb
    if not ok and feature.stochastic:
        again = render_feature(
            feature,
            spp=RERENDER_SPP * result.spp,
            seed=feature.seed + RERENDER_SEED_OFFSET,
            device=device,
            threads=threads,
            scene=scene,
        )
        out.rerendered = True
        # both renders pooled (5N spp), scored against the thresholds calibrated on such pooled
        # renders (a 5N-spp render at the 1x thresholds would pass more easily than the render it
        # stands in for); the Z-test's noise per pixel is the larger of the reference's and theirs
        # (two batches): a rare bright path one of them drew is noise
        both = [samples(result), samples(again)]
        rgb = pooled([result.rgb, again.rgb], both)
        noise = np.maximum(reference.variance, batch_variance([result.rgb, again.rgb], both))
        threshold = reference.calibration["rerender_ssim_threshold"]
        flip_threshold = reference.calibration["rerender_flip_threshold"]
        out.ssim_threshold, out.flip_threshold = threshold, flip_threshold
        out.ssim, out.flip, out.z, ok = score_render(
            feature, rgb, sum(both), reference, threshold, flip_threshold, noise
        )
    problem = image_problem(rgb)
    if problem:
        out.fail("finite", f"render has non-finite values: {problem}")
    else:
        if not out.ssim >= threshold:
            out.fail("ssim", f"SSIM {out.ssim:.4f} < threshold {threshold:.4f}")
        if not out.flip.criterion <= flip_threshold:
            out.fail("flip", f"{FLIP_CRITERION.upper()}-FLIP {out.flip.criterion:.4f} > threshold {flip_threshold:.4f}")
        if not out.z.passed:
            out.fail("z", f"Z-test: {out.z.rejected} pixel channels rejected (min p {out.z.min_p:.2e})")
    if feature.stochastic and not wrong:
        spps = [feature.spp, 4 * feature.spp, 16 * feature.spp]
        results = [result] + [
            render_feature(feature, spp=n, seed=feature.seed + k, device=device, threads=threads, scene=scene)
            for k, n in enumerate(spps[1:], 1)
        ]
        renders, counts = [r.rgb for r in results], [samples(r) for r in results]
        errors = [rmse(r, reference.rgb) for r in renders]
        # the three renders are independent: together, one estimate of sum(spps) samples per pixel
        pooled_spp = sum(spps)
        pooled_counts = sum(counts)
        pool = pooled(renders, counts)
        # noise: per pixel the larger of the reference's per-sample variance and this render's own
        variance = np.maximum(reference.variance, batch_variance(renders, counts))
        converged = z_test(pool, pooled_counts, reference.rgb, variance, reference.spp)
        out.convergence = {"spp": spps, "rmse": errors, "slope": convergence_slope(spps, errors), "z": converged}
        if not converged.passed:
            out.fail(
                "convergence",
                f"does not converge to the reference: the {pooled_spp}-spp pooled render's Z-test rejects "
                f"{converged.rejected} pixel channels (min p {converged.min_p:.2e})",
            )
        out.bias = bias_test(pool, pooled_counts, reference.rgb, variance, reference.spp)
        if not out.bias.passed:
            b = out.bias.image_bias
            out.fail(
                "bias",
                f"biased mean: |z| {out.bias.max_z:.1f} > {out.bias.threshold:.1f} at {out.bias.worst} "
                f"({pooled_spp} spp pooled; image mean {b[0]:+.2%} {b[1]:+.2%} {b[2]:+.2%})",
            )
    if feature.closed_form_mean is not None:
        made = list(zip(renders, spps)) if feature.stochastic and not wrong else [(result.rgb, result.spp)]
        if out.rerendered:  # independent of the others: its own seed
            made.append((again.rgb, again.spp))
        miss = closed_form_failure(feature.closed_form_mean, made, reference.variance)
        if miss:
            out.fail("closed_form", miss)
    out.images = {"render": rgb, "reference": reference.rgb, "ids": result.aovs["object_id"]}
    return out


def adaptive_failure(out: FeatureResult, feature: Feature, result, scene, device: str, threads: int | None) -> None:
    """Fail ``adaptive`` unless the adaptive render ``result`` is what its ``spp`` AOV says: every
    count in [``ADAPTIVE_FIRST_PASS``, spp], and each pixel that took n samples bit for bit the
    pixel of a plain render of n spp (a pixel's samples and their sum do not depend on how many
    the others took). Not for the stratified sampler, whose strata depend on the render's spp."""
    counts = result.aovs["spp"]
    if scene.render.sampler == "stratified":
        return
    if counts.min() < ADAPTIVE_FIRST_PASS or counts.max() > result.spp:
        out.fail(
            "adaptive",
            f"the spp AOV holds counts {counts.min()}..{counts.max()}, outside [{ADAPTIVE_FIRST_PASS}, {result.spp}]",
        )
        return
    for n in np.unique(counts):
        plain = render_feature(feature, spp=int(n), device=device, threads=threads, scene=scene, as_tested=False)
        took = counts == n
        differ = int(np.count_nonzero(np.any(result.rgb[took] != plain.rgb[took], axis=-1)))
        if differ:
            out.fail(
                "adaptive",
                f"{differ} of the {int(took.sum())} pixels whose spp AOV says {n} samples differ from a {n}-spp render",
            )
            return


def run_matrix(
    features: list[Feature],
    device: str = "cpu",
    jobs: int = 1,
    progress=None,
    refs: str | None = None,
    wrong: bool = False,
    cluster=None,
) -> list[FeatureResult]:
    """Evaluate ``features`` (or, with ``wrong``, their wrong variants) against their references
    in ``refs`` (see ``evaluate``), ``jobs`` at a time; ``progress(result)`` is called as each
    finishes. On ``cluster`` (a ``wrt.distributed.Cluster``), each feature's renders are one task
    and as many features run at once as the cluster has worker threads (``jobs`` is ignored).

    References are all loaded first, so a missing or stale one stops the run before any render.
    """
    for feature in features:
        load_reference(feature, refs)
    jobs = jobs if cluster is None else cluster.threads()
    threads = None if jobs <= 1 else max(1, (os.cpu_count() or 1) // jobs)

    def one(feature: Feature) -> FeatureResult:
        try:
            result = evaluate(feature, device=device, threads=threads, wrong=wrong, refs=refs, cluster=cluster)
        except WrtError:
            raise
        except Exception as e:  # a crash of the renderer is a failed feature, not a crashed run
            result = FeatureResult(feature=feature, passed=False)
            result.fail("crash", f"crashed: {e!r}\n{traceback.format_exc(limit=3)}")
        if progress:
            progress(result)
        return result

    if jobs <= 1:
        return [one(f) for f in features]
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        return list(pool.map(one, features))
