"""The ``wrt`` command: a thin dispatcher (parse, call, report). User errors exit with code 2."""
from __future__ import annotations

import argparse
import os
import sys

from .errors import WrtError

AOV_CHOICES = {"depth": "depth", "normal": "normal", "id": "object_id", "object_id": "object_id", "position": "position"}


def _aov_list(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == ["all"]:
        return ["depth", "normal", "object_id", "position"]
    unknown = [n for n in names if n not in AOV_CHOICES]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown AOV {unknown[0] if unknown else text!r} (choose from depth, normal, id, position, or all)")
    return list(dict.fromkeys(AOV_CHOICES[n] for n in names))


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="wrt", description="wrt: a ray tracer whose rendering runs as NVIDIA Warp kernels.")
    verbs = parser.add_subparsers(dest="verb", metavar="VERB", required=True)
    r = verbs.add_parser(
        "render",
        help="render a scene file to an image",
        description="Render a TOML scene file to an EXR (linear float RGB plus optional AOV channels) or PNG "
        "(tone mapped: clipped to [0, 1], sRGB, 8 bit). Options override the scene's [render] table.",
    )
    r.add_argument("scene", help="scene file (.toml); see docs/scene-format.md")
    r.add_argument("-o", "--output", required=True, help="output image, .exr or .png (written atomically)")
    r.add_argument("--spp", type=int, help="samples per pixel (default: the scene's [render] spp)")
    r.add_argument("--seed", type=int, help="random seed (default: the scene's [render] seed)")
    r.add_argument("--width", type=int, help="image width in pixels (default: the scene's)")
    r.add_argument("--height", type=int, help="image height in pixels (default: the scene's)")
    r.add_argument("--device", default="cpu", help="Warp device: cpu (default), cuda or cuda:N")
    r.add_argument("--threads", type=int, help="CPU threads launching image tiles (default: all cores)")
    r.add_argument(
        "--aov",
        type=_aov_list,
        default=[],
        help="comma-separated AOVs to add as EXR channels: depth (Z), normal (N.X,N.Y,N.Z), id (id), "
        "position (P.X,P.Y,P.Z), or all",
    )
    r.add_argument("--half", action="store_true", help="store EXR RGB as half floats (AOVs stay float32)")
    return parser


def _render(args) -> int:
    from . import __version__
    from .device import init_warp
    from .imageio import write_image
    from .loader import load_scene, override_render
    from .renderer import render

    if args.threads is not None and args.threads < 1:
        raise WrtError(f"--threads {args.threads}: must be >= 1")
    ext = os.path.splitext(args.output)[1].lower()
    if ext not in (".exr", ".png"):
        raise WrtError(f"{args.output}: unsupported output format {ext or '(none)'!r} (use .exr or .png)")
    if args.aov and ext != ".exr":
        raise WrtError(f"{args.output}: --aov needs an .exr output")
    messages = init_warp()
    if args.device.startswith("cuda") and messages:
        print(messages, end="", file=sys.stderr)
    scene = override_render(load_scene(args.scene), width=args.width, height=args.height, spp=args.spp, seed=args.seed)
    result = render(scene, device=args.device, threads=args.threads)
    metadata = {
        "version": __version__,
        "scene": os.path.abspath(args.scene),
        "spp": result.spp,
        "seed": result.seed,
        "integrator": result.integrator,
        "device": result.device,
        "render_time_s": result.render_time_s,
    }
    write_image(args.output, result.rgb, aovs={k: result.aovs[k] for k in args.aov}, metadata=metadata, half=args.half)
    h, w = result.rgb.shape[:2]
    print(
        f"wrote {args.output}: {w}x{h}, {result.spp} spp, {result.integrator}, {result.device} "
        f"({result.threads} thread{'s' if result.threads > 1 else ''}); BVH {result.build_time_s:.2f} s, "
        f"kernels {result.compile_time_s:.2f} s, render {result.render_time_s:.3f} s"
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return {"render": _render}[args.verb](args)
    except WrtError as e:
        print(f"wrt: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("wrt: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
