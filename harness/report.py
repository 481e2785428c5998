"""The matrix's HTML report: one static page and its PNGs, readable with no server.

One row per feature: reference, render, absolute-difference heat map, the FLIP error map (the
per-pixel FLIP of the pass criterion, ``flip.FLIP_CRITERION``, in FLIP's magma colours), the
geometry oracle pair (pyvista's rasterised ids and the ray tracer's ``object_id`` AOV through one
palette), a three-quarter view with the camera frustum, the scores against their thresholds, the
time, and pass/fail colouring; a checkbox shows failures only; the header names machine, device,
version.
"""

from __future__ import annotations

import datetime
import html
import os

import numpy as np

import wrt
from wrt.files import report_folder, write_atomic
from wrt.host import machine_line
from wrt.imageio import srgb_encode, write_image

from .flip import FLIP_CRITERION, error_map_image
from .matrix import load_feature_scene
from .oracle import overview, palette
from .run import FeatureResult

HEAT_SCALE = 0.25  # tone-mapped difference shown as full heat


def heat_map(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """|image - reference| of the tone-mapped images, channel mean, on a black-red-yellow-white
    ramp saturating at ``HEAT_SCALE``; returned as linear RGB for ``write_image``."""
    d = np.clip(np.abs(srgb_encode(image) - srgb_encode(reference)).mean(axis=-1) / HEAT_SCALE, 0, 1)
    srgb = np.stack([np.clip(3 * d, 0, 1), np.clip(3 * d - 1, 0, 1), np.clip(3 * d - 2, 0, 1)], axis=-1)
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4).astype(np.float32)


STYLE = """
body { font-family: sans-serif; margin: 1.5em; }
table { border-collapse: collapse; }
td, th { border: 1px solid #ccc; padding: 4px; vertical-align: top; font-size: 13px; }
tr.pass td.status { background: #c8f0c8; }
tr.fail td.status { background: #f4b4b4; font-weight: bold; }
tr.fail { background: #fff0f0; }
img { image-rendering: pixelated; width: 160px; }
.bad { color: #b00; font-weight: bold; }
body.failures-only tr.pass { display: none; }
"""


def _scores(r: FeatureResult) -> str:
    def mark(ok: bool, text: str) -> str:
        return text if ok else f'<span class="bad">{text}</span>'

    lines = [mark(r.ssim >= r.ssim_threshold, f"SSIM {r.ssim:.4f} &ge; {r.ssim_threshold:.4f}")]
    if r.flip is not None:
        lines.append(
            mark(
                r.flip.criterion <= r.flip_threshold,
                f"{FLIP_CRITERION.upper()}-FLIP {r.flip.criterion:.4f} &le; {r.flip_threshold:.4f} "
                f"(HDR {r.flip.hdr:.4f}, LDR {r.flip.ldr:.4f})",
            )
        )
    if r.z is not None:
        lines.append(
            mark(r.z.passed, f"Z-test min p {r.z.min_p:.2e} (level {r.z.threshold:.1e}), {r.z.rejected} rejected")
        )
    lines.append(
        mark(
            r.geometry_ssim >= r.feature.geometry_threshold,
            f"geometry SSIM {r.geometry_ssim:.4f} &ge; {r.feature.geometry_threshold:.2f}",
        )
    )
    lines.append(f"RMSE {r.rmse:.2e}, max error {r.max_error:.2e}")
    if r.convergence:
        z = r.convergence["z"]
        lines.append(
            mark(
                z.passed,
                f"converged: {sum(r.convergence['spp'])} spp pooled, Z-test min p {z.min_p:.1e} "
                f"(level {z.threshold:.1e}); RMSE slope {r.convergence['slope']:.2f}",
            )
        )
    if r.bias:
        b = r.bias
        lines.append(
            mark(
                b.passed,
                f"bias: max |z| {b.max_z:.1f} &le; {b.threshold:.1f} ({b.worst}); image mean "
                + " ".join(f"{x:+.2%}" for x in b.image_bias),
            )
        )
    if r.rerendered:
        lines.append("re-rendered at 4x spp")
    lines += [f'<span class="bad">{html.escape(f)}</span>' for f in r.failures]
    return "<br>".join(lines)


def write_report(results: list[FeatureResult], folder: str, device: str) -> str:
    """Write ``folder/index.html`` and its images, built in a new folder that then replaces
    ``folder`` (``wrt.files.report_folder``: only an earlier report is ever replaced, anything
    else is refused); returns the page's path."""
    with report_folder(folder, "wrt matrix") as work:
        rows = []
        for r in results:
            name = r.feature.name
            cells = []
            if r.images:
                pictures = {
                    "reference": r.images["reference"],
                    "render": r.images["render"],
                    "diff": heat_map(r.images["render"], r.images["reference"]),
                    "flip": error_map_image(r.images["render"], r.images["reference"]),
                    "raster_ids": palette(r.images["raster_ids"]),
                    "ids": palette(r.images["ids"]),
                }
                for key, image in pictures.items():
                    write_image(os.path.join(work, f"{name}.{key}.png"), image)
                overview(load_feature_scene(r.feature), os.path.join(work, f"{name}.overview.png"), size=(320, 240))
                for key in ("reference", "render", "diff", "flip", "raster_ids", "ids", "overview"):
                    cells.append(f'<td><img src="{name}.{key}.png" alt="{key}"></td>')
            else:
                cells = ['<td colspan="7">no images</td>']
            status = "pass" if r.passed else "fail"
            rows.append(
                f'<tr class="{status}" id="{name}"><td>{html.escape(name)}<br>'
                f"<small>{html.escape(r.feature.integrator)}, "
                f"{r.feature.width}x{r.feature.height}, {r.feature.spp} spp</small></td>"
                f'<td class="status">{status.upper()}</td>{"".join(cells)}<td>{_scores(r)}</td><td>{r.time_s:.2f} '
                "s</td></tr>"
            )
        failed = sum(not r.passed for r in results)
        header = (
            f"wrt {html.escape(wrt.__version__)} &middot; device {html.escape(device)} &middot; "
            f"{html.escape(machine_line())} &middot; "
            f"{datetime.datetime.now().isoformat(timespec='seconds')}"
        )
        page = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>wrt feature matrix</title><style>{STYLE}</style></head>
<body>
<h1>wrt feature matrix: {len(results) - failed} of {len(results)} pass</h1>
<p id="machine">{header}</p>
<p><label><input type="checkbox" id="failures-only"
  onchange="document.body.classList.toggle('failures-only', this.checked)"> show failures only</label>
&middot; heat map: |render - reference| of the tone-mapped images, white at {HEAT_SCALE}
&middot; FLIP: per-pixel {FLIP_CRITERION.upper()}-FLIP, magma (black 0, pale yellow 1)</p>
<table id="matrix">
<thead><tr><th>feature</th><th>status</th><th>reference</th><th>render</th><th>difference</th><th>FLIP</th>
<th>pyvista ids</th><th>ray-traced ids</th><th>scene and camera</th><th>scores</th><th>time</th></tr></thead>
<tbody>
{chr(10).join(rows)}
</tbody></table>
</body></html>
"""
        write_atomic(os.path.join(work, "index.html"), page)
    return os.path.join(folder, "index.html")
