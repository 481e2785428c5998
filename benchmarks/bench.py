"""Run time against error: how fast each sampler's error falls with wall time, and against Mitsuba 3.

``wrt bench`` renders each scene at a doubling series of spp (4, 8, 16, ...) for every sampler
(independent, stratified, sobol), with adaptive sampling off and on, until a curve has used its
time budget. Each curve starts with a warm-up render (kernel compilation, reported separately);
every point records

- ``render_s``: wall seconds of the render passes (``RenderResult.render_time_s``: no kernel
  loading, no BVH build),
- ``wall_s``: wall seconds from the scene file to the image in memory (scene parsing, BVH build,
  uploads, passes, read-back): how Mitsuba 3 is timed too (``mitsuba.load_file`` + ``mitsuba.render``),
- ``rmse`` of the linear RGB and ``one_minus_ssim`` of the tone-mapped sRGB image
  (``harness.score``) against the scene's converged reference.

The reference is a ``REFERENCE_SAMPLER`` render of about ``REFERENCE_TIME_FACTOR`` times a
curve's budget, made of two halves with different seeds: half their RMSE difference estimates the
reference's own RMSE (``reference.rmse_floor``; a measured RMSE near it is not resolved). It is
cached as ``DIR/references/NAME-HASH.exr`` (keyed by the scene's content and size) and reused while
it holds enough samples.

The slope of a curve is the least-squares slope of log error against log time (``render_s`` for
wrt, ``wall_s`` for Mitsuba): about -0.5 for a Monte Carlo estimator whose error is its noise, and
steeper where a sampler stratifies a smooth integrand.

For a Mitsuba 3 XML scene, Mitsuba (if importable: ``harness/mitsuba_peer.py``) renders the same
file at a doubling spp series too, with the same reference and metrics; the equal-time ratio is
wrt's error interpolated (log-log) at each of Mitsuba's times, divided by Mitsuba's error there
(below 1: wrt is better at equal time). On a scene with diffuse materials only, the specialised
kernel is timed against the all-features kernel (``wrt.render(..., specialize=False)``).

Results: ``DIR/results.json`` (everything), ``DIR/results.csv`` (one row per point) and
``DIR/NAME.png`` (log-log error against ``wall_s``, one line per curve), each written atomically.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import json
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources

import numpy as np
from wrt_harness import mitsuba_peer
from wrt_harness.references import REFERENCE_SEED
from wrt_harness.score import convergence_slope, rmse, ssim

import wrt
from wrt.device import resolve_device
from wrt.errors import WrtError
from wrt.files import check_output_folder, write_atomic, write_json
from wrt.host import machine_info
from wrt.imageio import read_image, write_image
from wrt.loader import load_scene, override_render, parse_scene
from wrt.mitsuba import load_mitsuba
from wrt.scene import Scene
from wrt.tables import text_table

from . import targets, wholeprocess
from .throughput import build_scaling, format_table, run_throughput

EXAMPLES = str(resources.files("wrt.examples"))  # the tree's examples/, installed with wrt
SAMPLERS = ("independent", "stratified", "sobol")
SEED = 1  # seed of the benchmark renders (the reference uses REFERENCE_SEED and REFERENCE_SEED + 1)
START_SPP = 4  # first point of a curve (spp = 1 would sample pixel centres only: another image)
MAX_SPP = 1 << 16
MIN_POINTS = 3  # a curve has at least this many points, whatever the budget
REPEATS = 2  # renders per point (same seed: the same image); the fastest time counts (the machine may be shared)
DEFAULT_BUDGET_S = 6.0  # render seconds per curve in the full run
QUICK_BUDGET_S = 0.5
FULL_TRIANGLES, FULL_RAYS = 1_000_000, 1 << 20  # the ray-throughput part (wrt_benchmarks.throughput)
QUICK_TRIANGLES, QUICK_RAYS = 20_000, 8192
BUILD_SIZES = (100_000, 1_000_000, 4_000_000)  # build time against size, on the CPU
PATH_SPP, QUICK_PATH_SPP = 256, 16  # the whole-process path-tracing comparison (harness.wholeprocess)
PATH_RES, QUICK_PATH_RES = 128, 32
WHOLE_PROCESS_REPEATS = 5
MIN_TRIANGLES = 1000
THROUGHPUT_REPEATS = 5
REFERENCE_SAMPLER = "sobol"
REFERENCE_TIME_FACTOR = 12.0  # the reference renders for about this many curve budgets
MIN_REFERENCE_SPP = 256
# Adaptive curves ask each pixel for a relative standard error of ADAPTIVE_K / sqrt(spp), spp
# being the curve point's maximum: the error a pixel whose single sample has a relative standard
# deviation of ADAPTIVE_K reaches with every sample. Smoother pixels stop early (at the checks
# after 16, 32, ... samples: wrt.renderer.ADAPTIVE_FIRST_PASS), so up to 16 spp adaptive
# renders are the plain ones.
ADAPTIVE_K = 1.0
SPEEDUP_REPEATS = 3  # timed renders per kernel in the specialisation measurement (best taken)
SPEEDUP_TARGET = 1.3
MITSUBA_VARIANT = (
    "llvm_ad_rgb"  # fastest CPU variant measured here (docs/mitsuba.md); the peer falls back to scalar_rgb
)


@dataclass(frozen=True)
class BenchScene:
    """A scene of the benchmark: a TOML file rendered at ``width`` x ``height`` (None: the file's
    size), or a Mitsuba 3 XML file whose ``<default>`` parameters ``params`` both renderers get."""

    path: str
    width: int | None = None
    height: int | None = None
    params: dict = field(default_factory=dict)
    speedup: bool = False  # also time the specialised against the all-features kernel here

    @property
    def name(self) -> str:
        """``FOLDER-STEM`` of the file (``mitsuba-cornell_box``): unique among the examples."""
        folder = os.path.basename(os.path.dirname(os.path.abspath(self.path)))
        return f"{folder}-{os.path.splitext(os.path.basename(self.path))[0]}"

    @property
    def is_mitsuba(self) -> bool:
        return self.path.lower().endswith(".xml")

    def load(self) -> Scene:
        if self.is_mitsuba:
            doc, _ = load_mitsuba(self.path, params=self.params)
            return parse_scene(doc, file=self.path, scene_dir=os.path.dirname(os.path.abspath(self.path)))
        return override_render(load_scene(self.path), width=self.width, height=self.height)


def _example(*parts: str) -> str:
    return os.path.join(EXAMPLES, *parts)


def shown_path(path: str) -> str:
    """``examples/...`` for one of wrt's examples (wherever installed), else the path as given."""
    inside = os.path.relpath(os.path.abspath(path), EXAMPLES)
    return path if inside.startswith("..") else os.path.join("examples", inside)


def default_scenes(quick: bool = False) -> list[BenchScene]:
    """The Cornell box with glass and mirror spheres (the Mitsuba twin and wrt's own) and a
    diffuse-only soft-shadow scene (smooth: where stratified and Sobol samples pay; the
    specialisation speed-up is measured on it). ``quick``: small images for the smoke test."""
    if quick:
        return [
            BenchScene(_example("mitsuba", "cornell_box.xml"), params={"res": 32}),
            BenchScene(_example("path", "soft_shadows.toml"), 40, 30, speedup=True),
        ]
    return [
        BenchScene(_example("mitsuba", "cornell_box.xml"), params={"res": 128}),
        BenchScene(_example("path", "cornell_box.toml"), 128, 128),
        BenchScene(_example("path", "soft_shadows.toml"), 160, 120, speedup=True),
    ]


def quick_size(bench: BenchScene, width: int = 40) -> BenchScene:
    """``bench`` at ``width`` pixels wide (its aspect kept, at least 8 pixels high) for ``--quick``."""
    r = bench.load().render
    return dataclasses.replace(bench, width=width, height=max(8, round(width * r.height / r.width)))


def scene_key(scene: Scene) -> str:
    """A short hash of everything the converged image depends on (not spp, seed or sampler)."""
    neutral = dataclasses.replace(
        scene, render=dataclasses.replace(scene.render, spp=1, seed=0, sampler=REFERENCE_SAMPLER)
    )
    h = hashlib.sha256(repr((neutral.render, neutral.camera, neutral.materials, neutral.lights)).encode())
    for shape in (*neutral.shapes, *(member for group in neutral.groups for member in group.shapes)):
        for f in dataclasses.fields(shape):  # arrays by their bytes: a repr rounds them to 8 digits
            value = getattr(shape, f.name)
            h.update(np.ascontiguousarray(value).tobytes() if isinstance(value, np.ndarray) else repr(value).encode())
    return h.hexdigest()[:16]


# --- one curve: a doubling spp series until the budget ---------------------------------------------


@dataclass
class Shot:
    """One timed render: linear RGB, seconds, and the mean samples a pixel took."""

    rgb: np.ndarray
    render_s: float | None  # passes only; None where the renderer does not say (Mitsuba)
    wall_s: float
    mean_spp: float


def measure_curve(
    render: Callable[[int], Shot],
    reference: np.ndarray,
    budget_s: float,
    max_points: int | None = None,
    repeats: int = REPEATS,
    log=None,
) -> list[dict]:
    """Render at ``START_SPP``, twice that, ... while the curve's time (``render_s``, else
    ``wall_s``) plus the next render's expected time (twice the last) fits in ``budget_s``; at
    least ``MIN_POINTS`` points, at most ``max_points``. Each point is rendered ``repeats``
    times with the same seed (the same image) and keeps the fastest times. Returns one dict per point."""
    points, spent, spp = [], 0.0, START_SPP
    while spp <= MAX_SPP:
        shots = [render(spp) for _ in range(repeats)]
        shot = shots[0]
        render_s = None if shot.render_s is None else min(s.render_s for s in shots)
        wall_s = min(s.wall_s for s in shots)
        seconds = wall_s if render_s is None else render_s
        spent += seconds
        points.append(
            {
                "spp": spp,
                "mean_spp": shot.mean_spp,
                "render_s": render_s,
                "wall_s": wall_s,
                "rmse": rmse(shot.rgb, reference),
                "one_minus_ssim": 1.0 - ssim(shot.rgb, reference),
            }
        )
        if log:
            log(
                f"    {spp:6d} spp  {seconds:8.3f} s  RMSE {points[-1]['rmse']:.4g}  1-SSIM "
                f"{points[-1]['one_minus_ssim']:.4g}"
            )
        if max_points is not None and len(points) >= max_points:
            break
        if len(points) >= MIN_POINTS and spent + 2.0 * seconds > budget_s:
            break
        spp *= 2
    return points


def slopes(points: list[dict]) -> dict:
    """Least-squares log-log slopes of RMSE and 1-SSIM against time (``render_s`` where known,
    else ``wall_s``), and of RMSE against spp."""
    time_key = "wall_s" if points[0]["render_s"] is None else "render_s"
    t = [p[time_key] for p in points]
    return {
        "slope_time": time_key,
        "slope_rmse": convergence_slope(t, [p["rmse"] for p in points]),
        "slope_one_minus_ssim": convergence_slope(t, [p["one_minus_ssim"] for p in points]),
        "slope_rmse_spp": convergence_slope([p["mean_spp"] for p in points], [p["rmse"] for p in points]),
    }


def wrt_shot(
    bench: BenchScene, sampler: str, device: str, adaptive: bool = False, seed: int = SEED, specialize: bool = True
) -> Callable[[int], Shot]:
    """A renderer for `measure_curve`: scene file -> ``wrt.render`` with ``sampler`` (and adaptive
    sampling) at a given spp, with the kernel specialised on the scene (every point alike,
    whatever its size), or the all-features kernel with ``specialize=False``."""

    def shoot(spp: int) -> Shot:
        t0 = time.perf_counter()
        scene = override_render(bench.load(), sampler=sampler)
        target = ADAPTIVE_K / math.sqrt(spp) if adaptive else None
        result = wrt.render(scene, spp=spp, seed=seed, device=device, target_error=target, specialize=specialize)
        wall = time.perf_counter() - t0
        mean_spp = float(np.mean(result.aovs["spp"])) if adaptive else float(result.spp)
        return Shot(result.rgb, result.render_time_s, wall, mean_spp)

    return shoot


def warm_up(bench: BenchScene, sampler: str, device: str, **options) -> dict:
    """Two small renders before timing: the first compiles and loads the kernels (its compile
    and BVH-build seconds are returned), the second measures the rate (``spp_per_s``)."""
    scene = override_render(bench.load(), sampler=sampler)
    options.setdefault("specialize", True)  # as the timed renders, whatever their size
    t0 = time.perf_counter()
    first = wrt.render(scene, spp=START_SPP, seed=SEED, device=device, **options)
    warmup = time.perf_counter() - t0
    rate = wrt.render(scene, spp=4 * START_SPP, seed=SEED, device=device, **options)
    return {
        "warmup_s": warmup,
        "compile_s": first.compile_time_s,
        "build_s": first.build_time_s,
        "spp_per_s": 4 * START_SPP / max(rate.render_time_s, 1e-9),
    }


# --- the reference ---------------------------------------------------------------------------------


def reference_image(bench: BenchScene, folder: str, spp: int, device: str, log=None) -> dict:
    """The converged image of ``bench``: the cached ``folder/NAME-HASH.exr`` when it holds at
    least ``spp`` samples, else a ``REFERENCE_SAMPLER`` render of ``spp`` in two halves of
    different seeds (written there). Returns ``rgb``, ``spp``, ``rmse_floor`` (half the RMSE
    between the halves: the reference's own RMSE), ``source`` and ``path``."""
    scene = override_render(bench.load(), sampler=REFERENCE_SAMPLER)
    path = os.path.join(folder, f"{bench.name}-{scene_key(scene)}.exr")
    cached = _cached_reference(path)
    if cached is not None and cached["spp"] >= spp:
        return cached
    if log:
        log(f"  reference: {REFERENCE_SAMPLER}, {spp} spp in two halves ...")
    half = max(1, spp // 2)
    t0 = time.perf_counter()
    a, b = (
        wrt.render(scene, spp=half, seed=REFERENCE_SEED + i, device=device).rgb.astype(np.float64) for i in range(2)
    )
    seconds = time.perf_counter() - t0
    rgb = (0.5 * (a + b)).astype(np.float32)
    floor = 0.5 * rmse(a, b)
    os.makedirs(folder, exist_ok=True)
    write_image(
        path,
        rgb,
        metadata={
            "spp": 2 * half,
            "seed": REFERENCE_SEED,
            "rmse_floor": floor,
            "render_time_s": seconds,
            "sampler": REFERENCE_SAMPLER,
            "scene": shown_path(bench.path),
        },
    )
    return {"rgb": rgb, "spp": 2 * half, "rmse_floor": floor, "source": "rendered", "path": path, "render_s": seconds}


def _cached_reference(path: str) -> dict | None:
    """The reference ``reference_image`` wrote to ``path`` (``rgb``, ``spp``, ``rmse_floor``...), or
    None when there is none or it is not one (unreadable, or metadata missing or not numbers): it
    is rendered again and replaces the file."""
    if not os.path.exists(path):
        return None
    try:
        cached = read_image(path)
        found = {
            "rgb": cached.rgb,
            "spp": int(cached.metadata["spp"]),
            "rmse_floor": float(cached.metadata["rmse_floor"]),
            "source": "cached",
            "path": path,
            "render_s": float(cached.metadata["render_time_s"]),
        }
    except (WrtError, KeyError, TypeError, ValueError):
        return None
    return found


def reference_spp(spp_per_s: float, budget_s: float) -> int:
    """A power of two of samples that the reference sampler renders in about
    ``REFERENCE_TIME_FACTOR * budget_s`` at ``spp_per_s``, at least ``MIN_REFERENCE_SPP``."""
    wanted = spp_per_s * REFERENCE_TIME_FACTOR * budget_s
    return max(MIN_REFERENCE_SPP, 1 << max(0, int(math.floor(math.log2(max(wanted, 1.0))))))


# --- Mitsuba 3 ---------------------------------------------------------------------------------------


def mitsuba_status() -> tuple[object | None, str]:
    """``(harness.mitsuba_peer, "mitsuba X, variant V")`` when Mitsuba 3 can render, else
    ``(None, why)``. The variant is the peer's: ``$WRT_MITSUBA_VARIANT`` (``wrt bench`` sets it
    to ``MITSUBA_VARIANT`` unless given), else scalar_rgb."""
    ok, why = mitsuba_peer.mitsuba_available()
    return (mitsuba_peer, why) if ok else (None, why)


def mitsuba_shot(peer, bench: BenchScene, seed: int = SEED) -> Callable[[int], Shot]:
    """A renderer for `measure_curve`: Mitsuba 3 from the XML file to the image, wall-timed."""

    def shoot(spp: int) -> Shot:
        t0 = time.perf_counter()
        rgb = peer.render_mitsuba(bench.path, spp=spp, seed=seed, **bench.params)
        return Shot(rgb, None, time.perf_counter() - t0, float(spp))

    return shoot


def equal_time(ours: list[dict], theirs: list[dict], metric: str) -> list[dict]:
    """At each of ``theirs``' wall times within ``ours``' range: our error interpolated in
    log-log, theirs, and ours / theirs."""
    t = np.log([p["wall_s"] for p in ours])
    e = np.log([p[metric] for p in ours])
    rows = []
    for p in theirs:
        x = math.log(p["wall_s"])
        if t[0] <= x <= t[-1]:
            value = float(np.exp(np.interp(x, t, e)))
            rows.append({"wall_s": p["wall_s"], "wrt": value, "mitsuba": p[metric], "ratio": value / p[metric]})
    return rows


def compare_mitsuba(curves: list[dict], mitsuba: dict, sampler: str) -> dict:
    """Equal-time ratios (RMSE and 1-SSIM) of each wrt curve against the Mitsuba curve, their
    geometric means, the best wrt curve by the RMSE ratio, and the curve of ``sampler`` (the
    scene's own, which Mitsuba uses) without adaptive sampling."""
    out = {}
    for c in curves:
        per = {m: equal_time(c["points"], mitsuba["points"], m) for m in ("rmse", "one_minus_ssim")}
        out[c["label"]] = {
            **{f"{m}_at": rows for m, rows in per.items()},
            **{
                f"{m}_ratio": float(np.exp(np.mean(np.log([r["ratio"] for r in rows])))) if rows else None
                for m, rows in per.items()
            },
        }
    ranked = [(v["rmse_ratio"], k) for k, v in out.items() if v["rmse_ratio"] is not None]
    best = min(ranked)[1] if ranked else None
    same = curve_label(sampler, False)
    return {
        "per_curve": out,
        "best": best,
        "best_rmse_ratio": out[best]["rmse_ratio"] if best else None,
        "target_met": bool(best and out[best]["rmse_ratio"] <= 1.0),
        "same_sampler": same,
        "same_sampler_rmse_ratio": out.get(same, {}).get("rmse_ratio"),
    }


# --- specialised against all-features kernel ----------------------------------------------------------


def specialisation_speedup(bench: BenchScene, device: str, seconds: float, log=None) -> dict:
    """Render time of the specialised kernel against the all-features one (``specialize=False``)
    on ``bench`` at the same spp (sized to about ``seconds`` per render), best of
    ``SPEEDUP_REPEATS`` each, alternating."""
    scene = bench.load()
    materials = sorted({m.type for m in scene.materials})
    for flag in (True, False):
        warm_up(bench, scene.render.sampler, device, specialize=flag)
    rate = warm_up(bench, scene.render.sampler, device, specialize=True)["spp_per_s"]
    spp = max(START_SPP, int(rate * seconds))
    best = {True: math.inf, False: math.inf}
    for _ in range(SPEEDUP_REPEATS):
        for flag in (True, False):
            best[flag] = min(best[flag], wrt_shot(bench, scene.render.sampler, device, specialize=flag)(spp).render_s)
    speedup = best[False] / best[True]
    if log:
        log(f"  specialised {best[True]:.3f} s, all-features {best[False]:.3f} s at {spp} spp: {speedup:.2f}x")
    return {
        "scene": bench.name,
        "materials": materials,
        "spp": spp,
        "specialised_s": best[True],
        "all_features_s": best[False],
        "speedup": speedup,
        "target": SPEEDUP_TARGET,
        "target_met": speedup >= SPEEDUP_TARGET,
    }


# --- the whole benchmark -----------------------------------------------------------------------------


def curve_label(sampler: str, adaptive: bool) -> str:
    return f"{sampler}{' adaptive' if adaptive else ''}"


def run(
    scenes: list[BenchScene],
    out_dir: str,
    budget_s: float,
    device: str = "cpu",
    max_points: int | None = None,
    repeats: int = REPEATS,
    samplers=SAMPLERS,
    mitsuba: bool = True,
    log=None,
) -> dict:
    """Run the benchmark over ``scenes`` and write ``out_dir/results.json``, ``results.csv`` and one
    plot per scene; returns the results (the JSON's content)."""
    log = log or (lambda text: None)
    peer, mitsuba_why = mitsuba_status() if mitsuba else (None, "not asked for")
    if peer is not None and not device.startswith("cpu"):
        peer, mitsuba_why = None, f"wrt runs on {device}: the comparison is CPU against CPU, run it with --device cpu"
    started = time.time()
    results = {
        "machine": {**machine_info(), "load_average_start": list(os.getloadavg())},
        "device": device,
        "wrt_version": wrt.__version__,
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z", time.localtime(started)),
        "budget_s": budget_s,
        "settings": {
            "start_spp": START_SPP,
            "min_points": MIN_POINTS,
            "max_points": max_points,
            "repeats": repeats,
            "seed": SEED,
            "adaptive_k": ADAPTIVE_K,
            "reference_sampler": REFERENCE_SAMPLER,
            "reference_time_factor": REFERENCE_TIME_FACTOR,
        },
        "mitsuba": mitsuba_why,
        "scenes": [],
        "speedup": None,
    }
    for bench in scenes:
        log(f"{bench.name}:")
        scene = bench.load()
        warm = warm_up(bench, REFERENCE_SAMPLER, device)
        ref = reference_image(
            bench, os.path.join(out_dir, "references"), reference_spp(warm["spp_per_s"], budget_s), device, log
        )
        log(
            f"  reference {ref['source']}: {ref['spp']} spp, RMSE floor {ref['rmse_floor']:.3g} "
            f"({os.path.relpath(ref['path'])})"
        )
        entry = {
            "name": bench.name,
            "path": shown_path(bench.path),
            "width": scene.render.width,
            "height": scene.render.height,
            "max_depth": scene.render.max_depth,
            "materials": sorted({m.type for m in scene.materials}),
            "reference": {k: v for k, v in ref.items() if k != "rgb"} | {"path": os.path.relpath(ref["path"], out_dir)},
            "curves": [],
        }
        for adaptive in (False, True):
            for sampler in samplers:
                label = curve_label(sampler, adaptive)
                curve = {"renderer": "wrt", "label": label, "sampler": sampler, "adaptive": adaptive}
                entry["curves"].append(curve)
                log(f"  {label}:")
                options = {"target_error": ADAPTIVE_K / math.sqrt(START_SPP)} if adaptive else {}
                curve.update(warm_up(bench, sampler, device, **options))
                curve["points"] = measure_curve(
                    wrt_shot(bench, sampler, device, adaptive), ref["rgb"], budget_s, max_points, repeats, log
                )
                curve.update(slopes(curve["points"]))
        if bench.is_mitsuba and peer is not None:
            log(f"  Mitsuba 3 ({mitsuba_why}):")
            shoot = mitsuba_shot(peer, bench)
            t0 = time.perf_counter()
            shoot(1)
            mi = {
                "renderer": "mitsuba",
                "label": f"Mitsuba 3 {peer.variant()}",
                "variant": peer.variant(),
                "warmup_s": time.perf_counter() - t0,
            }
            mi["points"] = measure_curve(shoot, ref["rgb"], budget_s, max_points, repeats, log)
            mi.update(slopes(mi["points"]))
            entry["mitsuba"] = mi
            entry["equal_time"] = compare_mitsuba(entry["curves"], mi, scene.render.sampler)
        elif bench.is_mitsuba:
            log(f"  Mitsuba 3 skipped: {mitsuba_why}")
        results["scenes"].append(entry)
        if bench.speedup:
            log("  specialised against all-features kernel:")
            results["speedup"] = specialisation_speedup(bench, device, min(2.0, budget_s / 2), log)
    results["machine"]["load_average_end"] = list(os.getloadavg())
    results["total_s"] = time.time() - started
    write_results(results, out_dir)
    return results


# --- files -------------------------------------------------------------------------------------------


CSV_COLUMNS = (
    "scene",
    "renderer",
    "curve",
    "sampler",
    "adaptive",
    "spp",
    "mean_spp",
    "render_s",
    "wall_s",
    "rmse",
    "one_minus_ssim",
)


def csv_text(results: dict) -> str:
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for entry in results["scenes"]:
        for c in entry["curves"] + ([entry["mitsuba"]] if "mitsuba" in entry else []):
            for p in c.get("points", []):
                w.writerow(
                    [
                        entry["name"],
                        c["renderer"],
                        c["label"],
                        c.get("sampler", c.get("variant")),
                        int(c.get("adaptive", False)),
                        p["spp"],
                        f"{p['mean_spp']:.6g}",
                        "" if p["render_s"] is None else f"{p['render_s']:.6g}",
                        f"{p['wall_s']:.6g}",
                        f"{p['rmse']:.6g}",
                        f"{p['one_minus_ssim']:.6g}",
                    ]
                )
    return out.getvalue()


def plot_png(entry: dict) -> bytes:
    """Log-log error against wall time, RMSE and 1-SSIM side by side, one line per curve."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.5), dpi=100)
    colours = {"independent": "tab:blue", "stratified": "tab:orange", "sobol": "tab:green"}
    for k, (metric, title) in enumerate((("rmse", "RMSE (linear)"), ("one_minus_ssim", "1 - SSIM (tone-mapped)"))):
        ax = fig.add_subplot(1, 2, k + 1)
        for c in entry["curves"] + ([entry["mitsuba"]] if "mitsuba" in entry else []):
            if not c.get("points"):
                continue
            t = [p["wall_s"] for p in c["points"]]
            style = (
                {"color": "black", "linestyle": "--", "marker": "s"}
                if c["renderer"] == "mitsuba"
                else {"color": colours.get(c["sampler"]), "linestyle": ":" if c["adaptive"] else "-", "marker": "o"}
            )
            ax.loglog(
                t,
                [p[metric] for p in c["points"]],
                label=f"{c['label']} ({c['slope_rmse' if metric == 'rmse' else 'slope_one_minus_ssim']:+.2f})",
                markersize=4,
                **style,
            )
        if metric == "rmse":
            ax.axhline(entry["reference"]["rmse_floor"], color="grey", linewidth=0.8, label="reference's own RMSE")
        ax.set_xlabel("wall seconds (scene file to image, after warm-up)")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, title="curve (slope vs time)", title_fontsize=7)
    fig.suptitle(f"{entry['name']} ({entry['width']} x {entry['height']}): error against time", fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def write_results(results: dict, out_dir: str) -> list[str]:
    """``results.json``, ``results.csv`` and ``NAME.png`` per scene in ``out_dir``, atomically."""
    files = {"results.json": (json.dumps(results, indent=1) + "\n").encode(), "results.csv": csv_text(results).encode()}
    files.update({f"{e['name']}.png": plot_png(e) for e in results["scenes"]})
    paths = []
    for name, data in files.items():
        paths.append(os.path.join(out_dir, name))
        write_atomic(paths[-1], data)
    return paths


def table(results: dict) -> str:
    """The readable summary: per curve its points, slopes and top spp; the Mitsuba ratios; the speed-up."""
    rows = [
        ["scene", "curve", "points", "spp", "render s", "RMSE", "1-SSIM", "slope RMSE/t", "slope 1-SSIM/t", "compile s"]
    ]
    lines = []
    for e in results["scenes"]:
        for c in e["curves"] + ([e["mitsuba"]] if "mitsuba" in e else []):
            last = c["points"][-1]
            seconds = last["wall_s"] if last["render_s"] is None else last["render_s"]
            rows.append(
                [
                    e["name"],
                    c["label"],
                    str(len(c["points"])),
                    f"{c['points'][0]['spp']}-{last['spp']}",
                    f"{seconds:.2f}",
                    f"{last['rmse']:.4g}",
                    f"{last['one_minus_ssim']:.4g}",
                    f"{c['slope_rmse']:+.2f}",
                    f"{c['slope_one_minus_ssim']:+.2f}",
                    f"{c.get('compile_s', 0.0):.2f}",
                ]
            )
        if "equal_time" in e:
            eq = e["equal_time"]
            for label, v in eq["per_curve"].items():
                if v["rmse_ratio"] is not None:
                    lines.append(
                        f"{e['name']}: wrt {label} / {e['mitsuba']['label']} at equal wall time: RMSE "
                        f"x{v['rmse_ratio']:.2f}, 1-SSIM x{v['one_minus_ssim_ratio']:.2f} "
                        f"(geometric mean over {len(v['rmse_at'])} times)"
                    )
            if eq["best"]:
                verdict = (
                    "target met"
                    if eq["target_met"]
                    else f"target NOT met: {100 * (eq['best_rmse_ratio'] - 1):.0f}% more RMSE than Mitsuba"
                )
                lines.append(
                    f"{e['name']}: best wrt curve {eq['best']}: RMSE ratio {eq['best_rmse_ratio']:.2f} ({verdict})"
                )
            if eq["same_sampler_rmse_ratio"] is not None:
                lines.append(
                    f"{e['name']}: with the scene's own sampler ({eq['same_sampler']}, as Mitsuba renders it): RMSE "
                    f"ratio {eq['same_sampler_rmse_ratio']:.2f}"
                )
    s = results.get("speedup")
    if s:
        lines.append(
            f"speed-up on {s['scene']}: specialised {s['specialised_s']:.3f} s vs all-features "
            f"{s['all_features_s']:.3f} s at {s['spp']} spp: {s['speedup']:.2f}x (target >= {s['target']})"
        )
    lines.append(f"Mitsuba 3: {results['mitsuba']}")
    return "\n".join([text_table(rows), "", *lines])


def peers(out_dir: str, speed: dict, triangles: int, device: str, quick: bool) -> dict:
    """Build time against size, the whole-process comparisons with Mitsuba 3, and the table of
    ``harness.targets``: printed, and written to ``out_dir/targets.json``."""
    log = lambda text: print(text, file=sys.stderr, flush=True)  # noqa: E731
    sizes = (max(MIN_TRIANGLES, triangles // 10), triangles) if quick else BUILD_SIZES
    log("build time against size:")
    builds = build_scaling(list(sizes), device, repeats=1 if quick else 3)
    repeats = 1 if quick else WHOLE_PROCESS_REPEATS
    log(f"whole process, {triangles:,}-triangle mesh, against Mitsuba 3:")
    mesh = wholeprocess.run_mesh(triangles, repeats, device, log)
    res, spp = (QUICK_PATH_RES, QUICK_PATH_SPP) if quick else (PATH_RES, PATH_SPP)
    cornell = BenchScene(wholeprocess.CORNELL_XML, params={"res": res})
    reference = reference_image(cornell, os.path.join(out_dir, "references"), MIN_REFERENCE_SPP, device, log)
    log(f"whole process, path tracing {os.path.basename(cornell.path)} at {spp} spp, against Mitsuba 3:")
    path = wholeprocess.run_path(
        spp, repeats, reference["rgb"].astype(np.float64), res, ("independent",) if quick else SAMPLERS, device, log
    )
    table = targets.rows(speed, builds, mesh, path)
    summary = {
        "machine": speed["machine"],
        "device": device,
        "build_scaling": builds,
        "whole_process_mesh": mesh,
        "whole_process_path": path,
        "table": table,
    }
    write_json(os.path.join(out_dir, "targets.json"), summary)
    lines = [
        f"{b['triangles']:>10,} triangles: wrt {b['wrt_s']:.3f} s (scene to device {b['wrt_scene_s']:.3f} s), wp.Mesh "
        f"{b['wp_mesh_s']:.3f} s"
        for b in builds
    ]
    print("\nBVH build against size (CPU):\n" + "\n".join(lines))
    print(
        "\nwrt against its peers (ratios above 1: wrt ahead):\n"
        + targets.format_rows(table, path)
        + f"\nwrote {out_dir}/targets.json"
    )
    return summary


def command(
    paths: list[str], budget_s: float | None, out_dir: str, device: str, quick: bool, triangles: int | None = None
) -> int:
    """``wrt bench``: run, print the tables, write the files; 0 on success. ``triangles``: size of
    the ray-throughput mesh (``wrt_benchmarks.throughput``; default 1M, 20k with ``quick``; 0 skips it)."""
    if budget_s is not None and not (budget_s > 0 and math.isfinite(budget_s)):
        raise WrtError(f"--budget {budget_s}: must be a positive number of seconds")
    triangles = (QUICK_TRIANGLES if quick else FULL_TRIANGLES) if triangles is None else triangles
    if triangles < 0 or 0 < triangles < MIN_TRIANGLES:
        raise WrtError(
            f"--triangles {triangles}: must be 0 (skip the throughput benchmark) or at least {MIN_TRIANGLES}"
        )
    for p in paths:
        if not os.path.isfile(p):
            raise WrtError(f"{p}: no such scene file")
        if not p.lower().endswith((".toml", ".xml")):
            raise WrtError(f"{p}: not a scene file (.toml or Mitsuba 3 .xml)")
    scenes = [BenchScene(p) for p in paths] or default_scenes(quick)
    if quick and paths:
        scenes = [s if s.is_mitsuba else quick_size(s) for s in scenes]
    outputs = ["results.json", "results.csv", *(f"{s.name}.png" for s in scenes)]
    outputs += ["throughput.json", "targets.json"] if triangles else []
    for folder, names in ((out_dir, outputs), (os.path.join(out_dir, "references"), ())):  # before the work
        check_output_folder(folder, names, option="-o", protect=tuple(paths))
    resolve_device(device)  # an unknown device or a missing GPU stops here too
    for s in scenes:
        s.load()  # bad scenes stop here, before anything is rendered
    budget = budget_s or (QUICK_BUDGET_S if quick else DEFAULT_BUDGET_S)
    os.environ.setdefault("WRT_MITSUBA_VARIANT", MITSUBA_VARIANT)
    results = run(
        scenes,
        out_dir,
        budget,
        device,
        max_points=3 if quick else None,
        repeats=1 if quick else REPEATS,
        log=lambda text: print(text, file=sys.stderr, flush=True),
    )
    print(table(results))
    print(
        f"\n{results['machine']['cpu']}, {results['machine']['cores']} cores, device {device}; "
        f"{results['total_s']:.0f} s; wrote {out_dir}/results.json, results.csv and plots"
    )
    if triangles:
        rays = QUICK_RAYS if quick else FULL_RAYS
        speed = run_throughput(
            triangles, rays, device=device, repeats=1 if quick else THROUGHPUT_REPEATS, reference_sah=not quick
        )
        speed["command"] = f"wrt bench (--triangles {triangles})"
        write_json(os.path.join(out_dir, "throughput.json"), speed)
        print("\n" + format_table(speed) + f"\nwrote {out_dir}/throughput.json")
        peers(out_dir, speed, triangles, device, quick)
    return 0
