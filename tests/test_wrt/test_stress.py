"""The stress suite (wrt/stress/, `wrt stress`) with a small ray budget: every case passes,
and the checks have teeth (they do fail on a mesh with a hole, or without the spawn offset)."""

import json

import numpy as np
import pytest

from wrt import stress
from wrt.cli import main
from wrt.stress import suite
from wrt.stress.common import CLOSED_MESHES, uv_sphere
from wrt.stress.offsets import SPAWN_ULPS, self_intersection
from wrt.stress.watertight import watertight_case

N = 20_000  # rays per ray-batch case (`wrt stress` uses 10^6)


def run(group, rays=N):
    rows = stress.run_suite(rays=rays, seed=1, only={group})
    assert rows, group
    return {row.case: row for row in rows}


def assert_all_pass(rows):
    failed = {name: (row.failures, row.worst, row.detail) for name, row in rows.items() if not row.passed}
    assert not failed, failed


@pytest.mark.parametrize(
    "group",
    [
        "watertight",
        "watertight-polygons",
        "self-intersection",
        "contact-shadows",
        "sphere-precision",
        "ulps",
        "grazing",
        "degenerate",
        "small-lights",
        "transport",
        "media",
        "zero-radius",
        "coincident",
        "zero-components",
        "critical-angle",
        "camera-inside",
        "not-finite",
    ],
)
def test_case_group_passes(group):
    assert_all_pass(run(group))


def test_watertight_reports_zero_leaks_per_mesh():
    rows = run("watertight")
    assert set(rows) == {f"watertight: {name}" for name in CLOSED_MESHES}
    for row in rows.values():
        assert row.rays >= N and row.detail == {"leaks_from_inside": 0, "leaks_from_outside": 0}


def test_watertight_check_finds_a_hole():
    """Take one triangle out of the tessellated sphere: rays aimed at its edges now leak."""
    v, f = uv_sphere()
    row = watertight_case("holed sphere", v, np.delete(f, 100, axis=0), 20_000, np.random.default_rng(0))
    assert not row.passed and row.failures > 0


def test_self_intersection_without_offset_fails():
    """Spawning from the raw hit point (offset scale 0) re-hits the surface: the check sees it."""
    totals, worst = self_intersection("sphere", 5_000, np.random.default_rng(0), offset_scales=(0.0, 1.0))
    judged, false_hits, escapes, _ = totals[0.0]
    assert false_hits + escapes > 100
    assert sum(totals[1.0][1:3]) == 0 and worst < SPAWN_ULPS


def test_self_intersection_measures_the_offset_needed():
    rows = run("self-intersection")
    for row in rows.values():
        needed = row.detail["smallest_offset_tried_without_failures_ulps"]
        assert needed <= row.detail["offset_used_ulps"] and row.worst < SPAWN_ULPS


def test_refraction_at_the_critical_angle_samples_it_densely():
    rows = run("critical-angle")
    assert_all_pass(rows)
    for row in rows.values():
        assert row.detail["pixels_within_1e-4_rad_of_critical"] > 100


def test_ior_one_is_invisible_at_the_origin():
    assert run("ior-one")["refraction: ior 1.0 is invisible (origin)"].passed


def test_ior_one_is_invisible_far_from_the_origin():
    assert run("ior-one")["refraction: ior 1.0 is invisible (1e4 from origin)"].passed


def test_high_ior_furnace_two_spheres():
    assert run("high-ior")["refraction: ior 4.0 furnace, two spheres"].passed


def test_high_ior_furnace_air_bubble():
    assert run("high-ior")["refraction: ior 4.0 furnace, air bubble in a sphere"].passed


def test_results_are_deterministic():
    a, b = (stress.run_suite(rays=2_000, seed=5, only={"sphere-precision"})[0] for _ in range(2))
    assert (a.failures, a.worst, a.detail) == (b.failures, b.worst, b.detail)


def test_cli_prints_the_table_writes_the_report_and_exits_by_the_result(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(suite, "CASES", [group for group in suite.CASES if group[0] in ("watertight", "grazing")])
    assert main(["stress", "--rays", "3000", "--seed", "2", "--report", str(tmp_path / "rep")]) == 0
    out = capsys.readouterr().out
    assert "watertight: bicone fan 256" in out and "grazing: rays along planes" in out and "4 of 4 cases pass" in out
    doc = json.loads((tmp_path / "rep" / "stress.json").read_text())
    assert doc["passed"] and doc["rays"] == 3000 and doc["seed"] == 2 and len(doc["cases"]) == 4
    assert "| watertight: uv sphere 64x32 | 3000 | 0 |" in (tmp_path / "rep" / "stress.md").read_text()

    def failing(rays, rng):
        return [stress.CaseResult("always fails", rays, 1)]

    monkeypatch.setattr(suite, "CASES", [("failing", failing)])
    assert main(["stress", "--rays", "10"]) == 1
    assert "FAIL" in capsys.readouterr().out


def test_cli_rejects_a_bad_ray_count(capsys):
    assert main(["stress", "--rays", "0"]) == 2
    assert "--rays 0: must be >= 1" in capsys.readouterr().err
