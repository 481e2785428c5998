"""Running the matrix: render each feature, score it against its reference and its geometry
oracle, tell noise from regressions, check convergence.

A feature passes when all hold:
- SSIM against the reference >= its calibrated threshold, and the per-pixel Z-test passes
  (a stochastic feature that misses either is re-rendered once at 4x spp: noise goes away,
  a real regression stays);
- SSIM of the ``object_id`` AOV against pyvista's rasterisation >= the geometry threshold;
- stochastic features: RMSE against the reference falls with spp at N, 4N, 16N with a log-log
  slope of at most ``CONVERGENCE_SLOPE_MAX`` (an unbiased estimator shows about -0.5; one that
  converges to the wrong image flattens toward 0);
- the render is finite: a NaN or Inf pixel fails the feature (it is never scored as black).
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

from .matrix import Feature, load_feature_scene
from .oracle import palette, rasterize_ids
from .references import ReferenceError, load_reference, render_feature
from .score import ZTest, convergence_slope, image_problem, max_error, rmse, ssim, z_test

CONVERGENCE_SLOPE_MAX = -0.35
RERENDER_SEED_OFFSET = 7919  # the 4x re-render draws samples independent of the first render's


@dataclass
class FeatureResult:
    feature: Feature
    passed: bool
    ssim: float = float("nan")
    ssim_threshold: float = float("nan")
    z: ZTest | None = None
    geometry_ssim: float = float("nan")
    rmse: float = float("nan")
    max_error: float = float("nan")
    time_s: float = 0.0
    rerendered: bool = False
    convergence: dict | None = None
    failures: list[str] = field(default_factory=list)
    images: dict = field(default_factory=dict)  # linear RGB / id images for the report


def score_render(feature: Feature, rgb: np.ndarray, spp: int, reference, threshold: float) -> tuple[float, ZTest, bool]:
    """SSIM (NaN for a render with NaN or Inf values, which fails), the Z-test, and whether both pass."""
    s = float("nan") if image_problem(rgb) else ssim(rgb, reference.rgb)
    z = z_test(rgb, spp, reference.rgb, reference.variance, reference.spp)
    return s, z, s >= threshold and z.passed


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
    out.geometry_ssim = ssim(palette(out.images["ids"]), palette(ids))
    if not out.geometry_ssim >= feature.geometry_threshold:
        out.failures.append(f"geometry SSIM {out.geometry_ssim:.4f} < {feature.geometry_threshold}")
    out.passed = not out.failures
    out.images["raster_ids"] = ids
    return out


def score_against_reference(
    feature: Feature, scene, reference, device: str = "cpu", threads: int | None = None, wrong: bool = False
) -> FeatureResult:
    """The part of ``evaluate`` that renders: render ``scene`` (the feature's, or its wrong
    variant's), score it against ``reference``, re-render a stochastic miss at 4x spp, check
    convergence. ``images["ids"]``: the first render's ``object_id`` AOV, for the geometry oracle."""
    threshold = float(reference.calibration["ssim_threshold"])
    start = time.perf_counter()
    result = render_feature(feature, device=device, threads=threads, scene=scene)
    elapsed = time.perf_counter() - start
    out = FeatureResult(feature=feature, passed=False, ssim_threshold=threshold, time_s=elapsed)
    out.ssim, out.z, ok = score_render(feature, result.rgb, result.spp, reference, threshold)
    out.rmse, out.max_error = rmse(result.rgb, reference.rgb), max_error(result.rgb, reference.rgb)
    rgb = result.rgb
    if not ok and feature.stochastic:
        again = render_feature(
            feature,
            spp=4 * result.spp,
            seed=feature.seed + RERENDER_SEED_OFFSET,
            device=device,
            threads=threads,
            scene=scene,
        )
        out.rerendered = True
        out.ssim, out.z, ok = score_render(feature, again.rgb, again.spp, reference, threshold)
        rgb = again.rgb
    problem = image_problem(rgb)
    if problem:
        out.failures.append(f"render has non-finite values: {problem}")
    elif not ok:
        out.failures.append(
            f"SSIM {out.ssim:.4f} (threshold {threshold:.4f}), Z-test "
            f"{'pass' if out.z.passed else f'{out.z.rejected} pixel channels rejected'}"
        )
    if feature.stochastic and not wrong:
        spps = [feature.spp, 4 * feature.spp, 16 * feature.spp]
        errors = [out.rmse] + [
            rmse(
                render_feature(feature, spp=n, seed=feature.seed + k, device=device, threads=threads, scene=scene).rgb,
                reference.rgb,
            )
            for k, n in enumerate(spps[1:], 1)
        ]
        slope = convergence_slope(spps, errors)
        out.convergence = {"spp": spps, "rmse": errors, "slope": slope}
        if not slope <= CONVERGENCE_SLOPE_MAX:  # NaN (a non-finite error) fails
            out.failures.append(f"RMSE does not converge: slope {slope:.2f} > {CONVERGENCE_SLOPE_MAX} over spp {spps}")
    out.images = {"render": rgb, "reference": reference.rgb, "ids": result.aovs["object_id"]}
    return out


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
            result = FeatureResult(
                feature=feature, passed=False, failures=[f"crashed: {e!r}\n{traceback.format_exc(limit=3)}"]
            )
        if progress:
            progress(result)
        return result

    if jobs <= 1:
        return [one(f) for f in features]
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        return list(pool.map(one, features))
