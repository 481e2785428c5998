"""False alarms of the matrix: how often a feature fails with no fault in the renderer.

A stochastic feature's checks (SSIM, Z-test, bias, FLIP, convergence, geometry, closed forms) are
random: each render draws other samples. ``false_alarms`` runs a feature's full scoring with
``seeds`` other than its own and counts, per check, the seeds at which it fails; the rate of the
feature (seeds with any failure / seeds) is what a developer sees as a red matrix on sound code.
``wrt refs false-alarms`` measures it; docs/harness.md records the figures.
"""

from __future__ import annotations

import dataclasses
import time

from .matrix import Feature, load_feature_scene
from .oracle import rasterize_ids
from .references import load_reference
from .run import check_geometry, score_against_reference

SEED_BASE = 2_000_000  # apart from the references' (1,000,000 + i) and the calibration's seeds
SEED_STRIDE = 10_000  # each run also draws seed + 1, seed + 2 and seed + RERENDER_SEED_OFFSET (7919)


def seeds(count: int) -> list[int]:
    """``count`` seeds whose runs share no sample stream with each other or with the references."""
    return [SEED_BASE + SEED_STRIDE * k for k in range(count)]


def false_alarms(
    feature: Feature, count: int, refs: str | None = None, device: str = "cpu", threads: int | None = None, log=None
) -> dict:
    """Score ``feature`` at ``count`` seeds of ``seeds`` against its reference: the number of
    failing seeds, per check and in all, and the failures' messages. ``log(seed, result)`` is
    called after each seed."""
    reference = load_reference(feature, refs)
    scene = load_feature_scene(feature)
    raster = rasterize_ids(scene)
    by_check: dict[str, int] = {}
    failing, messages = 0, []
    start = time.perf_counter()
    for seed in seeds(count):
        result = score_against_reference(dataclasses.replace(feature, seed=seed), scene, reference, device, threads)
        check_geometry(result, raster)
        for check in set(result.failed_checks):
            by_check[check] = by_check.get(check, 0) + 1
        if result.failures:
            failing += 1
            messages.append({"seed": seed, "failures": result.failures})
        if log:
            log(seed, result)
    return {
        "feature": feature.name,
        "seeds": count,
        "failing_seeds": failing,
        "rate": failing / count,
        "by_check": by_check,
        "failures": messages,
        "seconds": time.perf_counter() - start,
    }
