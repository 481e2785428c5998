"""Smoke test of the ray-throughput benchmark (``wrt_benchmarks.throughput``) on a small mesh.

It checks that the benchmark runs end to end through its command line and that its numbers are
sane: finite positive rates for every engine, ray set, query and thread setting, builds timed,
memory reported, and the engines agreeing ray by ray. It never checks a timing against a threshold.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from wrt.kernels.bvh import MAX_LEAF, STACK_SIZE
from wrt_benchmarks.throughput import (
    ENGINES,
    QUERIES,
    RAY_SETS,
    embree_version,
    format_table,
    main,
    torus_mesh,
)

TRIANGLES = 20_000
RAYS = 8192  # two tiles of wrt.renderer.TILE_PIXELS: the all-threads runs have work for two threads
# Embree's default (non-robust) triangle test is not watertight: a ray through a shared edge may
# slip through. Allowed: at most this fraction of rays; wrt and wp.Mesh (both watertight) must agree exactly.
EMBREE_MISMATCH_FRACTION = 1e-3


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    out = tmp_path_factory.mktemp("throughput") / "results.json"
    assert main(["--triangles", str(TRIANGLES), "--rays", str(RAYS), "--repeats", "1", "-o", str(out)]) == 0
    assert [p.name for p in out.parent.iterdir()] == ["results.json"]  # written by rename, no temporary left
    return json.loads(out.read_text())


def test_torus_mesh_is_closed_and_sized():
    vertices, faces = torus_mesh(TRIANGLES)
    assert abs(len(faces) - TRIANGLES) <= 0.01 * TRIANGLES
    assert np.isfinite(vertices).all()
    # closed and consistently wound: every directed edge appears once, and its reverse once
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    keys = edges[:, 0].astype(np.int64) * len(vertices) + edges[:, 1]
    reverse = edges[:, 1].astype(np.int64) * len(vertices) + edges[:, 0]
    assert len(np.unique(keys)) == len(keys)
    assert np.array_equal(np.sort(keys), np.sort(reverse))


def test_engines_present(results):
    expected = ["wrt", "wp.Mesh"] + (["Embree"] if embree_version() else [])
    assert results["engines"] == expected
    assert set(results["engines"]) <= set(ENGINES)


def test_rates_finite_and_positive(results):
    for ray_set in RAY_SETS:
        for query in QUERIES:
            for engine in results["engines"]:
                timing = results["throughput"][ray_set][query][engine]
                for label in ("per_thread", "all_threads"):
                    rate = timing[label]["mrays_per_s"]
                    assert math.isfinite(rate) and rate > 0, (ray_set, query, engine, label)
                    assert timing[label]["median_s"] > 0 and timing[label]["warmup_s"] > 0
                assert math.isfinite(timing["scaling"]) and timing["scaling"] > 0
    for ratios in results["ratios"].values():
        for per_query in ratios.values():
            for per_label in per_query.values():
                assert all(math.isfinite(r) and r > 0 for r in per_label.values())


def test_builds_and_memory_reported(results):
    for engine in results["engines"]:
        build = results["build"][engine]
        assert build["build_s"] > 0
    assert results["build"]["wrt"]["wide_nodes"] > 0 and results["build"]["wrt"]["sah_cost"] > 0
    assert 0 < results["build"]["wrt"]["stack_need"] <= STACK_SIZE
    for engine in ("wrt", "wp.Mesh"):
        assert results["build"][engine]["bvh_device_bytes"] > 0
        assert results["build"][engine]["triangles_device_bytes"] > 0
        assert results["compile_s"][engine] >= 0
    assert 1.0 <= results["build"]["wrt"]["mean_leaf_triangles"] <= MAX_LEAF


def test_engines_agree(results):
    for ray_set in RAY_SETS:
        assert 0.2 < results["rays"][ray_set]["hit_fraction"] < 0.9  # the rays see the mesh, and around it
        for query in QUERIES:
            agreement = results["agreement"][ray_set][query]
            assert agreement["wp.Mesh"]["mismatches"] == 0, (ray_set, query, agreement)


def test_embree_agrees(results):
    if "Embree" not in results["engines"]:
        pytest.skip("embreex is not installed (pip install -e '.[bench]')")
    for ray_set in RAY_SETS:
        for query in QUERIES:
            assert results["agreement"][ray_set][query]["Embree"]["mismatches"] <= EMBREE_MISMATCH_FRACTION * RAYS


def test_format_table(results):
    text = format_table(results)
    for engine in results["engines"]:
        assert f"{engine} Mrays/s" in text
    assert "wrt/wp.Mesh" in text
    assert ("wrt/Embree" in text) == ("Embree" in results["engines"])
    assert results["machine"]["cpu"] in text
