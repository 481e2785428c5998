"""Fingerprints of everything a restructuring must leave bit for bit unchanged.

    python -m wrt_benchmarks.identity record FILE [--jobs N]   # before the step
    python -m wrt_benchmarks.identity check FILE [--jobs N]    # after it: exit 1 on any difference

Cases: every example scene (``examples/**/*.toml`` and ``*.xml``) and every matrix entry with
its wrong variant, each rendered at 1 and 3 spp with the all-features kernel and with the
scene's specialised variant (SHA-256 of the image and of every AOV), with ray recordings of a
3 x 3 grid of pixels at 1 and 3 samples (SHA-256 of every recorded field); and every Mitsuba
XML example converted (the scene document and its warnings, strict and ``approximate``). Scenes
render at their own size and seed, on the CPU. A case that raises records its error message,
so a refusal must stay the same refusal. Both verbs also report every case whose specialised
render differs from its all-features one (they must be bit-identical: a specialised variant
that drew a blend's choice from 0 once rendered 2-5% bright), and then exit 1.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import glob
import hashlib
import json
import os
import subprocess
import sys

import numpy as np
import wrt.examples

EXAMPLES = os.path.dirname(os.path.abspath(wrt.examples.__file__))  # the installed examples, as the matrix's
SPPS = (1, 3)
GRID = 3  # ray recordings: GRID x GRID pixels


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:24]


def _mitsuba_files() -> list[str]:
    """Every Mitsuba XML example, the ``fragments`` that others ``<include>`` too."""
    return sorted(glob.glob(os.path.join(EXAMPLES, "mitsuba", "**", "*.xml"), recursive=True))


@functools.cache
def _features() -> dict:
    from wrt_harness.matrix import load_features

    return {feature.name: feature for feature in load_features()}


def scene_cases() -> list[str]:
    """Every rendered case: ``example:PATH``, ``feature:NAME`` and ``wrong:NAME``."""
    from wrt.aot import example_scenes

    cases = [f"example:{name}" for name in example_scenes()]
    for feature in _features().values():
        cases.append(f"feature:{feature.name}")
        if feature.wrong:
            cases.append(f"wrong:{feature.name}")
    return cases


def _load(case: str):
    from wrt_harness.matrix import load_feature_scene

    import wrt

    kind, name = case.split(":", 1)
    if kind == "example":
        return wrt.load_scene(os.path.join(EXAMPLES, name), approximate=True)
    return load_feature_scene(_features()[name], wrong=kind == "wrong")


def fingerprint(case: str) -> dict:
    """The fingerprints of one case (see the module docstring)."""
    import wrt
    from wrt.rays import grid_pixels, trace_rays

    try:
        scene = _load(case)
    except Exception as e:  # a refusal is part of the behaviour
        return {"error": f"{type(e).__name__}: {e}"}
    out = {}
    for spp in SPPS:
        for specialize in (False, True):
            key = f"spp{spp}_{'specialised' if specialize else 'all'}"
            try:
                r = wrt.render(scene, spp=spp, specialize=specialize, threads=1)
                out[key] = _digest(r.rgb, *(r.aovs[k] for k in sorted(r.aovs))) + f" rejected {r.rejected_samples}"
            except Exception as e:
                out[key] = f"error {type(e).__name__}: {e}"
        try:
            pixels = grid_pixels(scene.render.width, scene.render.height, GRID, GRID)
            tree = trace_rays(scene, pixels, samples=spp)
            fields = [f.name for f in dataclasses.fields(tree) if isinstance(getattr(tree, f.name), np.ndarray)]
            out[f"rays{spp}"] = _digest(*(getattr(tree, name) for name in sorted(fields)))
        except Exception as e:
            out[f"rays{spp}"] = f"error {type(e).__name__}: {e}"
    return out


def mitsuba_fingerprints() -> dict:
    """The converted document and warnings of every Mitsuba XML example, strict and approximate."""
    from wrt.mitsuba import load_mitsuba

    out = {}
    for path in _mitsuba_files():
        for approximate in (False, True):
            key = f"mitsuba:{os.path.relpath(path, EXAMPLES)}:{'approximate' if approximate else 'strict'}"
            try:
                doc, warnings = load_mitsuba(path, approximate=approximate)
                text = json.dumps([doc, warnings], sort_keys=True, default=repr)
                out[key] = hashlib.sha256(text.encode()).hexdigest()[:24]
            except Exception as e:
                out[key] = f"error {type(e).__name__}: {e}"
    return out


def collect(part: int, parts: int) -> dict:
    from wrt.device import init_warp

    init_warp()
    cases = scene_cases()[part::parts]
    result = {case: fingerprint(case) for case in cases}
    if part == 0:
        result.update(mitsuba_fingerprints())
    return result


def run_all(jobs: int) -> dict:
    """Every case, over ``jobs`` processes."""
    if jobs == 1:
        return collect(0, 1)
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "wrt_benchmarks.identity", "part", str(i), str(jobs)], stdout=subprocess.PIPE
        )
        for i in range(jobs)
    ]
    merged = {}
    for p in procs:
        out, _ = p.communicate()
        if p.returncode != 0:
            raise SystemExit(f"a part failed (exit {p.returncode})")
        merged.update(json.loads(out))
    return dict(sorted(merged.items()))


def specialisation_mismatches(result: dict) -> list[str]:
    """The cases of ``result`` whose specialised image differs from the all-features one at some spp."""
    return [
        case
        for case, prints in sorted(result.items())
        if isinstance(prints, dict)
        and any(
            prints.get(f"spp{spp}_specialised", "").split()[:1] != prints.get(f"spp{spp}_all", "").split()[:1]
            for spp in SPPS
        )
    ]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="verb", required=True)
    for verb in ("record", "check"):
        p = sub.add_parser(verb)
        p.add_argument("file")
        p.add_argument("--jobs", type=int, default=2)
    p = sub.add_parser("part")  # one process of run_all
    p.add_argument("part", type=int)
    p.add_argument("parts", type=int)
    args = parser.parse_args()
    if args.verb == "part":
        json.dump(collect(args.part, args.parts), sys.stdout)
        return 0
    from wrt.files import read_json, write_json

    before = read_json(args.file, "fingerprints") if args.verb == "check" else None
    result = run_all(args.jobs)
    unspecialised = specialisation_mismatches(result)
    for case in unspecialised:
        print(f"SPECIALISED DIFFERS {case}: {result[case]}")
    if args.verb == "record":
        write_json(args.file, result)
        print(f"{len(result)} cases recorded in {args.file}")
        return 1 if unspecialised else 0
    differ = 0
    for case in sorted(set(before) | set(result)):
        if before.get(case) != result.get(case):
            differ += 1
            print(f"DIFFERS {case}:\n  before {before.get(case)}\n  now    {result.get(case)}")
    checks = sum(len(v) if isinstance(v, dict) else 1 for v in result.values())
    print(
        f"{len(result)} cases, {checks} fingerprints: {differ} cases differ,"
        f" {len(unspecialised)} specialised renders differ from all-features ones"
    )
    return 1 if differ or unspecialised else 0


if __name__ == "__main__":
    sys.exit(main())
