"""wrt's benchmarks (installed as ``wrt_benchmarks``; ``wrt bench`` runs them, ``benchmarks/results``
holds the committed results, docs/performance.md reads them):

- ``bench``        error against run time per sampler, against Mitsuba 3, and the whole ``wrt bench``
- ``throughput``   rays per second of wrt's BVH against ``wp.Mesh`` and Embree; BVH build times
- ``wholeprocess`` command lines timed end to end against Mitsuba 3's
- ``targets``      every ratio of a run beside its target, in one table
- ``binned_sah``   the numpy binned-SAH builder, the reference for tree quality
- ``specialize``, ``threads``   specialised kernels and thread scaling (``python -m wrt_benchmarks.NAME``)
- ``first_render``, ``compile_options``, ``cuda_compile``   first renders on an empty kernel cache, what
  Warp's CPU compile options cost, the CUDA modules compiled to PTX (``python -m wrt_benchmarks.NAME``)
- ``identity``     fingerprints of every render, recorded before a restructuring and checked after it

It imports ``wrt`` and ``wrt_harness``; neither imports it.
"""

import json


def emit(results: dict, path: str | None) -> None:
    """Print a benchmark's ``results`` as JSON and, given ``path``, write them there too (atomically)."""
    if path:
        from wrt.files import write_json

        write_json(path, results)
    print(json.dumps(results, indent=1))
