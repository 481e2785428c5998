"""The suite: every case group in order, run with its own random stream, and ``wrt stress``."""

from __future__ import annotations

import sys
import time

import numpy as np

from ..device import init_warp
from ..files import check_report_folder
from .degenerate import (
    case_coincident,
    case_degenerate_triangles,
    case_plane_grazing,
    case_zero_components,
    case_zero_radius_sphere,
)
from .lights import case_small_lights
from .media import case_media
from .offsets import case_contact_shadows, case_self_intersection
from .precision import case_sphere_precision, case_ulps
from .refraction import (
    case_camera_inside,
    case_critical_angle,
    case_high_ior_furnace,
    case_ior_one,
    case_not_finite,
)
from .report import CaseResult, format_table, write_report
from .transport import case_transport
from .watertight import case_watertight, case_watertight_polygons

DEFAULT_RAYS = 10**6


CASES = [
    ("watertight", case_watertight),
    ("watertight-polygons", case_watertight_polygons),
    ("self-intersection", case_self_intersection),
    ("contact-shadows", case_contact_shadows),
    ("sphere-precision", case_sphere_precision),
    ("ulps", case_ulps),
    ("grazing", case_plane_grazing),
    ("degenerate", case_degenerate_triangles),
    ("zero-radius", case_zero_radius_sphere),
    ("coincident", case_coincident),
    ("zero-components", case_zero_components),
    ("critical-angle", case_critical_angle),
    ("ior-one", case_ior_one),
    ("high-ior", case_high_ior_furnace),
    ("camera-inside", case_camera_inside),
    ("not-finite", case_not_finite),
    ("small-lights", case_small_lights),
    ("transport", case_transport),
    ("media", case_media),
]


def run_suite(*, rays: int = DEFAULT_RAYS, seed: int = 0, only=None, progress=None) -> list[CaseResult]:
    """Run every case group (or those named in ``only``) with ``rays`` rays per ray-batch case.

    ``progress(result)`` is called after each row. Each group draws from its own random stream
    (seed, group index), so results do not depend on which other groups run.
    """
    if rays < 1:
        raise ValueError(f"rays must be >= 1, got {rays}")
    init_warp()
    results = []
    for index, (group, fn) in enumerate(CASES):
        if only is not None and group not in only:
            continue
        start = time.perf_counter()
        rows = fn(rays, np.random.default_rng([seed, index]))
        elapsed = (time.perf_counter() - start) / len(rows)
        for row in rows:
            row.seconds = elapsed
            results.append(row)
            if progress:
                progress(row)
    return results


def command(rays: int, seed: int, report: str | None) -> int:
    """``wrt stress``: run the suite, print the table (and write the report); 0 if all pass, else 1."""
    if report:
        check_report_folder(report)  # before the work, not after it
    start = time.perf_counter()
    results = run_suite(
        rays=rays,
        seed=seed,
        progress=lambda r: print(
            f"  {'pass' if r.passed else 'FAIL'}  {r.case} ({r.seconds:.1f} s)", file=sys.stderr, flush=True
        ),
    )
    print(format_table(results))
    failed = [r for r in results if not r.passed]
    print(
        f"\n{len(results) - len(failed)} of {len(results)} cases pass; N = {rays} rays, seed {seed}, "
        f"{time.perf_counter() - start:.0f} s"
    )
    if report:
        print("wrote " + ", ".join(write_report(results, report, rays, seed)))
    return 1 if failed else 0
