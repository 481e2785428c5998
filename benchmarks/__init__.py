"""wrt's benchmarks (installed as ``wrt_benchmarks``; ``wrt bench`` runs them, ``benchmarks/results``
holds the committed results, docs/performance.md reads them):

- ``bench``        error against run time per sampler, against Mitsuba 3, and the whole ``wrt bench``
- ``throughput``   rays per second of wrt's BVH against ``wp.Mesh`` and Embree; BVH build times
- ``wholeprocess`` command lines timed end to end against Mitsuba 3's
- ``targets``      every ratio of a run beside its target, in one table
- ``binned_sah``   the numpy binned-SAH builder, the reference for tree quality
- ``specialize``, ``threads``   specialised kernels and thread scaling (``python -m wrt_benchmarks.NAME``)

It imports ``wrt`` and ``wrt_harness``; neither imports it.
"""
