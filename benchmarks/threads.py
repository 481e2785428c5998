"""Thread-pool speed-up of CPU rendering: the same render with 1 thread and with all cores.

    python benchmarks/threads.py [SCENE] [--width W --height H --spp N --repeats R] [-o results.json]

Reports the median wall time of the kernel launches (BVH build and kernel compilation excluded,
done once before timing) and checks that the images are bit-identical.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import wrt
from wrt.device import init_warp
from wrt.files import write_json
from wrt.host import default_threads, machine_line
from wrt.loader import override_render


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene", nargs="?", default="examples/showcase.toml")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=720)
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("-o", "--output", help="write the results as JSON here")
    args = parser.parse_args()
    init_warp()
    scene = override_render(wrt.load_scene(args.scene), width=args.width, height=args.height, spp=args.spp)
    rows = []
    images = {}
    for threads in sorted({1, default_threads()}):
        wrt.render(scene, threads=threads)  # warm-up: compile, caches
        times = []
        for _ in range(args.repeats):
            result = wrt.render(scene, threads=threads)
            times.append(result.render_time_s)
        images[threads] = result.rgb
        rows.append({"threads": threads, "median_s": statistics.median(times), "min_s": min(times), "times_s": times})
    base = rows[0]["median_s"]
    for row in rows:
        row["speedup"] = base / row["median_s"]
        row["mrays_per_s"] = args.width * args.height * (args.spp + 1) / row["median_s"] / 1e6
    identical = all(np.array_equal(images[1], img) for img in images.values())
    report = {
        "scene": args.scene,
        "width": args.width,
        "height": args.height,
        "spp": args.spp,
        "primary_rays_per_image": args.width * args.height * (args.spp + 1),
        "machine": machine_line(),
        "date": time.strftime("%Y-%m-%d"),
        "wrt": wrt.__version__,
        "bit_identical": identical,
        "rows": rows,
    }
    print(f"{args.scene} {args.width}x{args.height} {args.spp} spp (+1 AOV ray per pixel), {report['machine']}")
    print("| threads | median render s | Mrays/s | speed-up |")
    print("|---|---|---|---|")
    for row in rows:
        print(f"| {row['threads']} | {row['median_s']:.3f} | {row['mrays_per_s']:.2f} | {row['speedup']:.2f}x |")
    print(f"images bit-identical across thread counts: {identical}")
    if args.output:
        write_json(args.output, report)


if __name__ == "__main__":
    main()
