"""Smoke test of the run-time-against-error benchmark (benchmarks/bench.py, ``wrt bench``).

It checks that the benchmark runs and that its numbers are sane (finite, error falling with spp,
slopes computed, files written); never a timing threshold.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os

import numpy as np
import pytest
from wrt_benchmarks import bench
from wrt_benchmarks.targets import TARGETS

from wrt.cli import main


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """``wrt bench --quick --triangles 2000``, once for the module: its folder, its results and
    what it printed."""
    out = tmp_path_factory.mktemp("bench")
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main(["bench", "--quick", "--triangles", "2000", "-o", str(out)]) == 0
    with open(out / "results.json") as f:
        return out, json.load(f), printed.getvalue()


def test_files_are_written(quick_run):
    out, results, _ = quick_run
    with open(out / "results.json") as f:
        assert json.load(f)["scenes"][0]["name"] == results["scenes"][0]["name"]
    with open(out / "results.csv") as f:
        rows = list(csv.DictReader(f))
    points = sum(len(c.get("points", [])) for e in results["scenes"] for c in e["curves"] + [e.get("mitsuba", {})])
    assert len(rows) == points > 0
    for e in results["scenes"]:
        assert (out / f"{e['name']}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert os.path.exists(out / e["reference"]["path"])
    assert not [p for p in os.listdir(out) if p.startswith(".")]  # no temporary files left


def test_error_falls_with_spp_and_slopes_are_computed(quick_run):
    _, results, _ = quick_run
    curves = [c for e in results["scenes"] for c in e["curves"] + ([e["mitsuba"]] if "mitsuba" in e else [])]
    assert {c["sampler"] for c in curves if c["renderer"] == "wrt"} == set(bench.SAMPLERS)
    for c in curves:
        points = c["points"]
        assert [p["spp"] for p in points] == [4, 8, 16]
        for p in points:
            assert all(math.isfinite(p[k]) and p[k] > 0 for k in ("wall_s", "rmse", "one_minus_ssim", "mean_spp"))
        assert points[-1]["rmse"] < points[0]["rmse"], c["label"]
        assert points[-1]["one_minus_ssim"] < points[0]["one_minus_ssim"], c["label"]
        # Error against spp is deterministic; against time it carries the machine's timing noise
        # (three points 0.1 s apart), so a time slope is only required to exist.
        assert c["slope_rmse_spp"] < 0, c["label"]
        assert math.isfinite(c["slope_rmse"]) and math.isfinite(c["slope_one_minus_ssim"]), c["label"]
    for e in results["scenes"]:
        assert 0 < e["reference"]["rmse_floor"] < min(p["rmse"] for c in e["curves"] for p in c.get("points", []))


def test_mitsuba_and_speedup_parts(quick_run):
    _, results, _ = quick_run
    cornell = results["scenes"][0]
    if bench.mitsuba_status()[0] is None:
        assert "mitsuba" not in cornell
    else:
        # Ratios exist only at Mitsuba times inside a wrt curve's time range, which depends on the
        # machine's speed: check each ratio against its own points, never whether there are any.
        equal = cornell["equal_time"]
        assert equal["same_sampler"] == "independent"  # the XML's sampler
        for label, curve in equal["per_curve"].items():
            rows = curve["rmse_at"]
            assert (curve["rmse_ratio"] is None) == (not rows), label
            if rows:
                assert math.isfinite(curve["rmse_ratio"]) and all(
                    r["ratio"] == pytest.approx(r["wrt"] / r["mitsuba"]) for r in rows
                )
        ranked = [c["rmse_ratio"] for c in equal["per_curve"].values() if c["rmse_ratio"] is not None]
        assert equal["best_rmse_ratio"] == (min(ranked) if ranked else None)
    s = results["speedup"]
    assert s["materials"] == ["diffuse"] and math.isfinite(s["speedup"]) and s["speedup"] > 0


def test_equal_time_interpolates_log_log():
    ours = [{"wall_s": t, "rmse": 1 / math.sqrt(t)} for t in (0.1, 1.0, 10.0)]
    theirs = [{"wall_s": t, "rmse": 2 / math.sqrt(t)} for t in (0.05, 0.3, 3.0, 20.0)]
    rows = bench.equal_time(ours, theirs, "rmse")
    assert [r["wall_s"] for r in rows] == [0.3, 3.0]  # only times inside our range
    assert np.allclose([r["ratio"] for r in rows], 0.5)


def test_reference_is_cached(tmp_path):
    scene = bench.quick_size(bench.BenchScene(bench._example("path", "soft_shadows.toml")), width=16)
    first = bench.reference_image(scene, str(tmp_path), 8, "cpu")
    again = bench.reference_image(scene, str(tmp_path), 8, "cpu")
    more = bench.reference_image(scene, str(tmp_path), 16, "cpu")
    assert (first["source"], again["source"], more["source"]) == ("rendered", "cached", "rendered")
    assert np.array_equal(first["rgb"], again["rgb"]) and more["spp"] == 16


@pytest.mark.parametrize(
    "argv, named",
    [
        (["bench", "no/such/scene.toml"], "no/such/scene.toml"),
        (["bench", "--budget", "-1"], "--budget -1"),
        (["bench", "README.md"], "README.md"),
        (["bench", "--triangles", "12"], "--triangles 12"),
    ],
)
def test_bad_input_is_one_line_exit_2(argv, named, capsys, tmp_path):
    assert main(argv + ["-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wrt: error:") and named in err and "\n" not in err


def test_command_line_runs_both_parts(quick_run):
    """`wrt bench --quick --triangles N`: the error curves and the ray-throughput table."""
    folder, results, out = quick_run
    assert "Ray throughput" in out and "wrt/wp.Mesh" in out
    with open(folder / "throughput.json") as f:
        speed = json.load(f)
    assert 1500 < speed["mesh"]["triangles"] <= 2000 and speed["command"] == "wrt bench (--triangles 2000)"  # about N
    assert [e["name"] for e in results["scenes"]] == [s.name for s in bench.default_scenes(quick=True)]
    # the table against the peers: every row present, every measured ratio finite and positive
    assert "wrt against its peers" in out
    with open(folder / "targets.json") as f:
        targets = json.load(f)
    assert [r["row"] for r in targets["table"]] == list(TARGETS)
    for r in targets["table"]:
        assert r["ratio"] is None or (math.isfinite(r["ratio"]) and r["ratio"] > 0), r
        assert r["met"] == (None if r["ratio"] is None else r["ratio"] >= r["target"])
    assert [b["triangles"] for b in targets["build_scaling"]] == sorted(
        b["triangles"] for b in targets["build_scaling"]
    )
    path = targets["whole_process_path"]
    for name in ("wrt", "Mitsuba") if "Mitsuba" in path else ("wrt",):
        # 16 spp against a 256-spp reference of the same scene: the error is the image's noise
        assert 0 < path[name]["mse"] < 0.5 and path[name]["median_s"] > 0
    assert targets["whole_process_mesh"]["wrt"]["median_s"] > 0
