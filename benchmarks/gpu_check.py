"""GPU readiness in one call: ``benchmarks/gpu_check.sh [--device cuda] [--quick] [-o REPORT.md]``.

On a CUDA machine it runs, one after the other, each as a child process with a time limit:

1. ``tests``: the device-parametrised tests (the ``device`` fixture of ``tests/conftest.py``) on
   DEVICE: ``python -m pytest -q`` over the collected node ids whose parameters name the device
   (``[cuda]``, or ``[cpu]`` for a dry run);
2. ``matrix``: ``wrt matrix --device DEVICE``: every feature against its (CPU-made) reference;
3. ``agreement``: every matrix entry rendered at its test spp and seed on the CPU and on DEVICE
   (``python -m wrt_benchmarks.gpu_check agree``); the SSIM of one against the other must reach
   the entry's calibrated SSIM threshold, the matrix's own bar for a render against its reference;
4. ``throughput``: ``python -m wrt_benchmarks.throughput --device DEVICE``: rays/s of wrt's BVH
   and ``wp.Mesh`` (and Embree, on the CPU, when installed) on a 1M-triangle mesh;
5. ``path``: ``wrt bench --device DEVICE --triangles 0``: error against time of the path-traced
   benchmark scenes, per sampler, adaptive sampling off and on.

and writes a short Markdown report (default ``benchmarks/results/gpu_check.md``, atomically): the
machine, one row per step (pass, FAIL or timed out, seconds, its summary line), the agreement
table, and the end of the log of every step that did not pass. The steps' logs and outputs go to
a folder beside the report (``gpu_check/``). Exit code 0 when every step passed, 1 otherwise.

The whole run stays inside ``BUDGET_S`` (under the 8 minutes asked): each step may use its
share (``STEPS``) plus whatever the earlier steps left. The integrators' all-features and recording
modules and the library's come with wrt as PTX (``wrt.aot.install_cuda``: loaded, not compiled,
where the driver reads Warp's PTX); the report counts, per step, the modules wrt announced
compiling (``wrt: compiled ...``) and their seconds, so a run shows whether they were.

``--quick`` is a dry run of the script itself, on a tiny subset (a few tests, two matrix entries,
a 20k-triangle throughput mesh, ``wrt bench --quick``); with ``--device cpu`` it runs anywhere.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time

from wrt.files import write_atomic, write_json

BUDGET_S = 450.0  # the whole run, seconds
STEPS = {"tests": 140.0, "matrix": 120.0, "agreement": 60.0, "throughput": 45.0, "path": 85.0}  # shares of BUDGET_S
QUICK_TESTS = 4  # device tests a --quick run takes
QUICK_FEATURES = ("raycast_sphere", "hard_shadows")  # matrix entries a --quick run takes
LOG_LINES = 15  # lines of a failed step's log shown in the report


def device_id(device: str) -> str:
    """The test id of ``device`` in the ``device`` fixture's parameters: ``cuda`` or ``cpu``."""
    return "cuda" if device.startswith("cuda") else "cpu"


def device_tests(node_ids: list[str], device: str) -> list[str]:
    """The node ids of tests parametrised over ``device`` (``test_x[cuda]``, ``test_y[2-cuda]``)."""
    pattern = re.compile(rf"\[(?:[^\]]*-)?{device_id(device)}(?:-[^\]]*)?\]$")
    return [line for line in node_ids if pattern.search(line)]


def collect_tests() -> list[str]:
    """The node ids of the suite (``pytest --collect-only -q``)."""
    command = [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", "tests"]
    return subprocess.run(command, capture_output=True, text=True).stdout.splitlines()


def step_commands(device: str, quick: bool, work: str) -> dict[str, list[str]]:
    """The command line of each step but ``tests`` (whose node ids are collected when it runs)."""
    python, features = sys.executable, list(QUICK_FEATURES) if quick else []
    agreement = ["agree", *features, "--device", device, "-o", os.path.join(work, "agreement.json")]
    throughput = ["--triangles", "20000", "--rays", "65536", "--repeats", "1"] if quick else []
    bench = ["--quick"] if quick else ["--budget", "2"]
    return {
        "matrix": [python, "-m", "wrt", "matrix", *features, "--device", device],
        "agreement": [python, "-m", "wrt_benchmarks.gpu_check", *agreement],
        "throughput": [python, "-m", "wrt_benchmarks.throughput", "--device", device, *throughput]
        + ["-o", os.path.join(work, "throughput.json")],
        "path": [python, "-m", "wrt", "bench", "--device", device, "--triangles", "0", *bench]
        + ["-o", os.path.join(work, "bench")],
    }


def summary_line(name: str, log: str) -> str:
    """The line of a step's output that says how it went."""
    lines = [line.strip() for line in log.splitlines() if line.strip()]
    wanted = {
        "tests": r"\d+ (passed|failed)|no tests ran|error",
        "matrix": r"\d+ passed, \d+ failed",
        "agreement": r"entries agree",
        "throughput": r"^wrote",  # replaced by throughput_summary
        "path": r"best wrt curve",
    }[name]
    found = [line for line in lines if re.search(wanted, line)]
    return (found[-1] if found else lines[-1] if lines else "(no output)")[:160]


COMPILED = re.compile(r"^wrt: compiled (\S+) for (\S+) in ([\d.]+) s", re.M)


def compilations(log: str) -> str:
    """How many modules a step's log announces compiling (``wrt.aot.load``), and their seconds."""
    seconds = [float(m.group(3)) for m in COMPILED.finditer(log)]
    return f"{len(seconds)}, {sum(seconds):.0f} s" if seconds else "0"


def throughput_summary(path: str) -> str:
    """Closest-hit Mrays/s (all threads) of wrt and ``wp.Mesh`` from a ``throughput.json``."""
    with open(path) as f:
        speed = json.load(f)["throughput"]
    rates = [
        f"{rays} wrt {speed[rays]['closest']['wrt']['all_threads']['mrays_per_s']:.3g}, wp.Mesh "
        f"{speed[rays]['closest']['wp.Mesh']['all_threads']['mrays_per_s']:.3g}"
        for rays in ("coherent", "incoherent")
    ]
    return "closest hit, Mrays/s: " + "; ".join(rates)


def run_step(name: str, command: list[str], limit_s: float, work: str) -> dict:
    """Run one step, in a process group of its own that is killed whole at ``limit_s`` seconds;
    its log goes to ``work/NAME.log``."""
    start = time.perf_counter()
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    with subprocess.Popen(
        command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    ) as child:
        try:
            log, _ = child.communicate(timeout=limit_s)
            status = "pass" if child.returncode == 0 else f"FAIL (exit {child.returncode})"
        except subprocess.TimeoutExpired:
            os.killpg(child.pid, signal.SIGKILL)  # the step and whatever it started
            log, _ = child.communicate()
            status = f"timed out ({limit_s:.0f} s)"
    seconds = time.perf_counter() - start
    write_atomic(os.path.join(work, f"{name}.log"), log)
    print(f"gpu_check: {name}: {status}, {seconds:.1f} s", file=sys.stderr, flush=True)
    return {
        "step": name,
        "command": shlex.join(command),
        "status": status,
        "seconds": seconds,
        "summary": summary_line(name, log),
        "compiled": compilations(log),
        "tail": log.splitlines()[-LOG_LINES:],
    }


def machine(device: str) -> str:
    """One line naming the device, the CPU and the versions."""
    import warp as wp

    from wrt.device import init_warp, resolve_device
    from wrt.host import machine_info

    init_warp()
    info = machine_info()
    try:
        name = resolve_device(device).name
    except Exception as e:  # reported, not fatal: the steps say what fails
        name = f"unavailable ({e})"
    return (
        f"device {device}: {name}; CPU {info['cpu']}, {info['cores']} cores; {info['system']}; Python "
        f"{info['python']}, Warp {wp.__version__}"
    )


def report(device: str, quick: bool, steps: list[dict], agreement: list[dict] | None, total_s: float) -> str:
    lines = [
        f"# GPU check{' (quick dry run)' if quick else ''}",
        "",
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {machine(device)}; {total_s:.0f} s in all "
        f"(budget {BUDGET_S:.0f} s).",
        "",
        "| step | result | seconds | modules compiled | summary |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| {s['step']} | {s['status']} | {s['seconds']:.1f} | {s['compiled']} | {s['summary'].replace('|', '/')} |"
        for s in steps
    ]
    if agreement:
        lines += [
            "",
            f"## {device} against the CPU, per matrix entry (test spp and seed)",
            "",
            "| feature | SSIM | threshold | max abs difference | agree |",
            "|---|---|---|---|---|",
        ]
        lines += [
            f"| {a['feature']} | {a['ssim']:.5f} | {a['threshold']:.4f} | {a['max_abs']:.3g} | "
            f"{'yes' if a['agree'] else 'NO'} |"
            for a in agreement
        ]
    for s in steps:
        if s["status"] != "pass":
            lines += ["", f"## {s['step']}: {s['status']}", "", f"`{s['command']}`", "", "```", *s["tail"], "```"]
    return "\n".join(lines) + "\n"


def check(device: str, quick: bool, output: str) -> int:
    """Run the steps, write the report to ``output``; 0 when every step passed."""
    if not os.path.isfile(os.path.join("tests", "conftest.py")):
        raise SystemExit("gpu_check: run it from the root of a wrt checkout (benchmarks/gpu_check.sh does)")
    work = os.path.join(os.path.dirname(os.path.abspath(output)), "gpu_check")
    os.makedirs(work, exist_ok=True)
    agreement_file, throughput_file = (os.path.join(work, f"{name}.json") for name in ("agreement", "throughput"))
    for stale in (agreement_file, throughput_file):  # an earlier run's results must not be reported
        if os.path.exists(stale):
            os.remove(stale)
    start = time.perf_counter()
    commands = step_commands(device, quick, work)
    steps = []
    for i, name in enumerate(STEPS):
        command = commands.get(name)
        if name == "tests":
            ids = device_tests(collect_tests(), device)[: QUICK_TESTS if quick else None]
            if not ids:  # pytest without ids would run the whole suite
                steps.append(
                    {
                        "step": name,
                        "command": "pytest --collect-only",
                        "status": "FAIL",
                        "seconds": 0.0,
                        "summary": "no test parametrised over the device was collected",
                        "compiled": "0",
                        "tail": [],
                    }
                )
                continue
            command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *ids]
        later = sum(list(STEPS.values())[i + 1 :])
        limit = max(1.0, BUDGET_S - (time.perf_counter() - start) - later)
        steps.append(run_step(name, command, limit, work))
    if os.path.exists(throughput_file):
        next(s for s in steps if s["step"] == "throughput")["summary"] = throughput_summary(throughput_file)
    agreement = None
    if os.path.exists(agreement_file):
        with open(agreement_file) as f:
            agreement = json.load(f)
    write_atomic(output, report(device, quick, steps, agreement, time.perf_counter() - start))
    print(f"gpu_check: wrote {output}", file=sys.stderr)
    return 0 if all(s["status"] == "pass" for s in steps) else 1


def agree(names: list[str], device: str, output: str) -> int:
    """Render every matrix entry (or those named) at its test spp and seed on the CPU and on
    ``device``; an entry agrees when the SSIM of the ``device`` image against the CPU one reaches
    its calibrated threshold. Writes the table to ``output`` (JSON); 0 when all agree."""
    import numpy as np
    from wrt_harness.matrix import load_features, select
    from wrt_harness.references import load_reference, render_feature
    from wrt_harness.score import ssim

    from wrt.device import init_warp

    init_warp()
    rows = []
    for feature in select(load_features(), names):
        threshold = float(load_reference(feature).calibration["ssim_threshold"])
        cpu, other = (render_feature(feature, device=d).rgb for d in ("cpu", device))
        score = float(ssim(other, cpu))
        rows.append(
            {
                "feature": feature.name,
                "ssim": score,
                "threshold": threshold,
                "max_abs": float(np.abs(other.astype(np.float64) - cpu).max()),
                "agree": score >= threshold,
            }
        )
        print(f"{feature.name}: SSIM {score:.5f} (threshold {threshold:.4f})", flush=True)
    write_json(output, rows)
    agreed = sum(r["agree"] for r in rows)
    print(f"{agreed} of {len(rows)} entries agree")
    return 0 if agreed == len(rows) else 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="benchmarks/gpu_check.sh", description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cuda", help="the device under test (default cuda; cpu: a dry run)")
    parser.add_argument("--quick", action="store_true", help="a tiny subset: checks the script, measures nothing")
    parser.add_argument(
        "-o", "--output", default=os.path.join("benchmarks", "results", "gpu_check.md"), help="the report (Markdown)"
    )
    actions = parser.add_subparsers(dest="action")
    a = actions.add_parser("agree", help="step 3 alone: CPU against DEVICE images of matrix entries")
    a.add_argument("features", nargs="*", metavar="FEATURE")
    a.add_argument("--device", default="cuda")
    a.add_argument("-o", "--output", required=True, help="the table, JSON")
    args = parser.parse_args(argv)
    if args.action == "agree":
        return agree(args.features, args.device, args.output)
    return check(args.device, args.quick, args.output)


if __name__ == "__main__":
    sys.exit(main())
