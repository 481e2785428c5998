"""The matrix's HTML report: one static page and its PNGs, readable with no server and nothing
fetched from elsewhere, from 1280 px wide up.

At the top a summary: how many features passed and failed, the failed ones linked, the total
time, the machine, device and version, and how many kinds of the scene format the features
exercise. Then one row per feature, failures first: a line naming it, its status and time; its
images (reference, render, absolute-difference heat map, the FLIP error map of the pass criterion
``flip.FLIP_CRITERION`` in FLIP's magma colours, the geometry oracle's pair: pyvista's rasterised
ids and the ray tracer's ``object_id`` AOV through one palette, a three-quarter view with the
camera frustum); its checks against their thresholds, beside the images where the window is wide
enough and under them where not, and its failures. A click on an image enlarges it; there a click
or the space bar flips it in place with its partner (reference and render, the two id images, the
two error maps), the arrow keys step through the feature's images and Escape closes it. Last the
coverage table (``coverage.py``): every kind of the scene format and the features of the report
that exercise it. A checkbox shows failures only.
"""

from __future__ import annotations

import datetime
import html
import json
import os

import numpy as np

import wrt
from wrt.errors import WrtError
from wrt.files import report_folder, write_atomic
from wrt.host import machine_line
from wrt.imageio import srgb_encode, write_image

from .coverage import coverage, empty
from .flip import FLIP_CRITERION, error_map_image
from .matrix import load_feature_scene
from .oracle import overview, palette
from .run import FeatureResult

HEAT_SCALE = 0.25  # tone-mapped difference shown as full heat
# the images of a row, by the key in their file names, with their captions
PICTURES = {
    "reference": "reference",
    "render": "render",
    "diff": "difference",
    "flip": "FLIP",
    "raster_ids": "pyvista ids",
    "ids": "ray-traced ids",
    "overview": "scene and camera",
}
# what a click on an enlarged image flips it to, in place
PAIRS = {
    "reference": "render",
    "render": "reference",
    "raster_ids": "ids",
    "ids": "raster_ids",
    "diff": "flip",
    "flip": "diff",
}


def heat_map(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """|image - reference| of the tone-mapped images, channel mean, on a black-red-yellow-white
    ramp saturating at ``HEAT_SCALE``; returned as linear RGB for ``write_image``."""
    d = np.clip(np.abs(srgb_encode(image) - srgb_encode(reference)).mean(axis=-1) / HEAT_SCALE, 0, 1)
    srgb = np.stack([np.clip(3 * d, 0, 1), np.clip(3 * d - 1, 0, 1), np.clip(3 * d - 2, 0, 1)], axis=-1)
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4).astype(np.float32)


STYLE = """
* { box-sizing: border-box; }
body { font-family: sans-serif; font-size: 14px; margin: 0 24px 24px; color: #222; }
h1 { font-size: 22px; margin: 16px 0 8px; }
h2 { font-size: 18px; margin: 24px 0 8px; }
a { color: #14c; }
#summary p { margin: 4px 0; }
.badge { display: inline-block; padding: 1px 8px; border-radius: 4px; font-weight: bold; }
.badge.pass { background: #c8f0c8; }
.badge.fail { background: #f4b4b4; }
.legend { color: #555; font-size: 12px; }
#matrix, #matrix > tbody { display: block; }
#matrix > tbody > tr { display: flex; flex-wrap: wrap; align-items: flex-start; gap: 6px 16px; margin: 0 0 10px;
  padding: 8px; border: 1px solid #ccc; border-left: 6px solid #4a4; }
#matrix > tbody > tr.fail { border-left-color: #c33; background: #fff4f4; }
#matrix td { display: block; padding: 0; min-width: 0; }
td.head { flex: 0 0 100%; }
td.head .name { font-size: 16px; font-weight: bold; }
td.head small { color: #555; }
#matrix td.images { display: flex; flex-wrap: wrap; gap: 6px; }
figure { margin: 0; }
figcaption { font-size: 11px; color: #555; text-align: center; }
td.images img { display: block; width: 144px; height: auto; image-rendering: pixelated; cursor: zoom-in; }
td.scores { flex: 1 1 340px; }
ul.checks { columns: 300px; column-gap: 16px; margin: 0; padding: 0; list-style: none; font-size: 13px; }
ul.checks li { break-inside: avoid; padding: 1px 0 1px 18px; text-indent: -18px; overflow-wrap: anywhere; }
ul.checks li::before { display: inline-block; width: 18px; text-indent: 0; content: ""; }
ul.checks li.ok::before { content: "\\2713"; color: #282; }
ul.checks li.bad { color: #b00; font-weight: bold; }
ul.checks li.bad::before { content: "\\2717"; }
ul.failures { margin: 4px 0 0; padding-left: 18px; color: #b00; font-size: 13px; overflow-wrap: anywhere;
  white-space: pre-wrap; }
body.failures-only #matrix tr.pass { display: none; }
#coverage table { border-collapse: collapse; width: 100%; }
#coverage td, #coverage th { border: 1px solid #ccc; padding: 3px 6px; text-align: left; vertical-align: top; }
#coverage td:nth-child(-n + 2) { white-space: nowrap; }
#coverage td:nth-child(3) { width: 100%; overflow-wrap: anywhere; }
#coverage tr.missing td { background: #f4b4b4; font-weight: bold; }
#coverage a.fail { color: #b00; }
#viewer { position: fixed; inset: 0; z-index: 10; display: flex; align-items: center; justify-content: center;
  background: rgba(0, 0, 0, 0.88); }
#viewer[hidden] { display: none; }
#viewer figure { max-width: 100%; }
#viewer img { display: block; height: auto; image-rendering: pixelated; cursor: pointer; }
#viewer figcaption { color: #eee; font-size: 14px; margin-top: 6px; }
"""

# the enlarged view: a click on an image of a row opens it, as large as the window allows; a click
# on the enlarged image or the space bar flips it with its partner (PAIRS), the arrow keys step
# through the row's images, Escape or a click beside the image closes it
SCRIPT = """
const viewer = document.getElementById("viewer"), big = document.getElementById("viewer-image");
const caption = document.getElementById("viewer-caption");
let shown = null;
function show(img) {
  shown = img;
  big.src = img.getAttribute("src");
  big.alt = img.alt;
  const scale = Math.min(0.94 * innerWidth / img.naturalWidth, 0.86 * innerHeight / img.naturalHeight);
  big.style.width = `${Math.floor(img.naturalWidth * scale)}px`;
  big.dataset.kind = img.dataset.kind;
  const partner = PAIRS[img.dataset.kind];
  const flip = partner ? `click or space: ${img.closest("tr").querySelector(`img[data-kind="${partner}"]`).alt}; `
    : "";
  caption.textContent = `${img.closest("tr").id}: ${img.alt} (${flip}\\u2190 \\u2192: other images; Esc: close)`;
  viewer.hidden = false;
}
function flip() {
  const partner = PAIRS[shown.dataset.kind];
  if (partner) show(shown.closest("tr").querySelector(`img[data-kind="${partner}"]`));
}
function step(by) {
  const all = [...shown.closest("tr").querySelectorAll("img[data-kind]")];
  show(all[(all.indexOf(shown) + by + all.length) % all.length]);
}
function close() { viewer.hidden = true; shown = null; }
document.getElementById("matrix").addEventListener("click", (e) => {
  const img = e.target.closest("img[data-kind]");
  if (img) show(img);
});
big.addEventListener("click", (e) => { e.stopPropagation(); flip(); });
viewer.addEventListener("click", close);
document.addEventListener("keydown", (e) => {
  if (viewer.hidden) return;
  const act = { " ": flip, Escape: close, ArrowRight: () => step(1), ArrowLeft: () => step(-1) }[e.key];
  if (act) { e.preventDefault(); act(); }
});
"""


LINES = ("ssim", "flip", "z", "geometry", "convergence", "bias")  # the checks (run.CHECKS) _checks shows as lines


def _checks(r: FeatureResult) -> list[tuple[bool | None, str]]:
    """The feature's scores as (passed, HTML) lines: passed None for a number that is not judged."""
    checks = [(r.ssim >= r.ssim_threshold, f"SSIM {r.ssim:.4f} &ge; {r.ssim_threshold:.4f}")]
    if r.flip is not None:
        checks.append(
            (
                r.flip.criterion <= r.flip_threshold,
                f"{FLIP_CRITERION.upper()}-FLIP {r.flip.criterion:.4f} &le; {r.flip_threshold:.4f} "
                f"(HDR {r.flip.hdr:.4f}, LDR {r.flip.ldr:.4f})",
            )
        )
    if r.z is not None:
        checks.append(
            (r.z.passed, f"Z-test min p {r.z.min_p:.2e} (level {r.z.threshold:.1e}), {r.z.rejected} rejected")
        )
    checks.append(
        (
            r.geometry_ssim >= r.feature.geometry_threshold,
            f"geometry SSIM {r.geometry_ssim:.4f} &ge; {r.feature.geometry_threshold:.2f}",
        )
    )
    if r.convergence:
        z = r.convergence["z"]
        checks.append(
            (
                z.passed,
                f"converged: {sum(r.convergence['spp'])} spp pooled, Z-test min p {z.min_p:.1e} "
                f"(level {z.threshold:.1e}); RMSE slope {r.convergence['slope']:.2f}",
            )
        )
    if r.bias:
        b = r.bias
        checks.append(
            (
                b.passed,
                f"bias: max |z| {b.max_z:.1f} &le; {b.threshold:.1f} ({html.escape(b.worst)}); image mean "
                + " ".join(f"{x:+.2%}" for x in b.image_bias),
            )
        )
    if r.feature.closed_form_mean is not None:
        mean = ", ".join(f"{c:.4g}" for c in r.feature.closed_form_mean)
        checks.append(("closed_form" not in r.failed_checks, f"closed-form image mean [{mean}]"))
    checks.append((None, f"RMSE {r.rmse:.2e}, max error {r.max_error:.2e}"))
    if r.rerendered:
        checks.append((None, "re-rendered at 4x spp"))
    return checks


def _scores(r: FeatureResult) -> str:
    """The feature's checks as a list (ticked or crossed), and under it the messages of its
    failures that no line of the list shows (a non-finite render, a closed form, a crash); a
    feature that made no images (it crashed) has its messages only."""
    marks = {True: ' class="ok"', False: ' class="bad"', None: ""}
    lines = "".join(f"<li{marks[ok]}>{text}</li>" for ok, text in _checks(r)) if r.images else ""
    shown = LINES if r.images else ()
    failures = "".join(
        f"<li>{html.escape(f)}</li>" for f, check in zip(r.failures, r.failed_checks) if check not in shown
    )
    return f'<ul class="checks">{lines}</ul>' + (f'<ul class="failures">{failures}</ul>' if failures else "")


def _row(r: FeatureResult, scene, work: str) -> str:
    """The feature's row; its images are written to ``work`` (the overview drawn from ``scene``)."""
    name = r.feature.name
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
        overview(scene, os.path.join(work, f"{name}.overview.png"), size=(320, 240))
        images = "".join(
            f'<figure><img src="{html.escape(name)}.{key}.png" alt="{caption}" data-kind="{key}">'
            f"<figcaption>{caption}</figcaption></figure>"
            for key, caption in PICTURES.items()
        )
    else:
        images = "no images"
    status = "pass" if r.passed else "fail"
    feature = r.feature
    return (
        f'<tr class="{status}" id="{html.escape(name)}"><td class="head">'
        f'<span class="name">{html.escape(name)}</span> <span class="badge {status}">{status.upper()}</span> '
        f"<small>{html.escape(feature.integrator)}, {feature.width}x{feature.height}, {feature.spp} spp "
        f"&middot; render {r.time_s:.2f} s</small></td>"
        f'<td class="images">{images}</td><td class="scores">{_scores(r)}</td></tr>'
    )


def _coverage_section(rows, results: list[FeatureResult]) -> str:
    """The coverage table: every kind of the scene format and the features that exercise it."""
    status = {r.feature.name: "pass" if r.passed else "fail" for r in results}
    lines = []
    for row in rows:
        links = ", ".join(f'<a href="#{html.escape(n)}" class="{status[n]}">{html.escape(n)}</a>' for n in row.features)
        lines.append(
            f"<tr{'' if row.features else ' class=missing'}><td>{html.escape(row.group)}</td>"
            f"<td>{html.escape(row.kind)}</td><td>{links or 'no feature'}</td></tr>"
        )
    missing = len(empty(rows))
    return (
        '<section id="coverage"><h2>Coverage</h2>'
        f"<p>Every kind of the scene format and the features of this report that exercise it: "
        f"{len(rows) - missing} of {len(rows)} kinds exercised, {missing} by none "
        "(<code>wrt matrix --coverage</code>; docs/harness.md says what counts).</p>"
        "<table><thead><tr><th>group</th><th>kind</th><th>features</th></tr></thead><tbody>"
        + "\n".join(lines)
        + "</tbody></table></section>"
    )


def _summary(results: list[FeatureResult], device: str, total_s: float | None, rows) -> str:
    """The page's top: counts, the failed features linked, the time (``total_s``: the run's wall
    time, if known), machine, coverage."""
    failed = [r.feature.name for r in results if not r.passed]
    renders = f"the test renders took {sum(r.time_s for r in results):.1f} s"
    timing = renders if total_s is None else f"total time {total_s:.1f} s ({renders} of it)"
    links = ", ".join(f'<a href="#{html.escape(n)}">{html.escape(n)}</a>' for n in failed) or "none"
    missing, passed = len(empty(rows)), len(results) - len(failed)
    machine = (
        f"wrt {html.escape(wrt.__version__)} &middot; device {html.escape(device)} &middot; "
        f"{html.escape(machine_line())} &middot; {datetime.datetime.now().isoformat(timespec='seconds')}"
    )
    return f"""<header id="summary">
<h1>wrt feature matrix: {passed} of {len(results)} pass</h1>
<p id="counts"><span class="badge fail">{len(failed)} failed</span> <span class="badge pass">{passed} passed</span>
&middot; {timing}</p>
<p id="failed">failed: {links}</p>
<p id="machine">{machine}</p>
<p>coverage: {len(rows) - missing} of {len(rows)} kinds of the scene format exercised, {missing} by none
(<a href="#coverage">table</a>)</p>
<p class="legend"><label><input type="checkbox" id="failures-only"
  onchange="document.body.classList.toggle('failures-only', this.checked)"> show failures only</label>
&middot; click an image to enlarge it, then click it or press space to flip reference and render in place
&middot; heat map: |render - reference| of the tone-mapped images, white at {HEAT_SCALE}
&middot; FLIP: per-pixel {FLIP_CRITERION.upper()}-FLIP, magma (black 0, pale yellow 1)</p>
</header>"""


def _scene(result: FeatureResult):
    """The feature's scene, for its overview and the coverage table; None when it does not load
    (the feature crashed: its row says so)."""
    try:
        return load_feature_scene(result.feature)
    except WrtError:
        return None


def write_report(results: list[FeatureResult], folder: str, device: str, *, total_s: float | None = None) -> str:
    """Write ``folder/index.html`` and its images, built in a new folder that then replaces
    ``folder`` (``wrt.files.report_folder``: only an earlier report is ever replaced, anything
    else is refused); returns the page's path. ``total_s``: the run's wall time in seconds (None:
    not known, the summary gives the time of the test renders only)."""
    with report_folder(folder, "wrt matrix") as work:
        scenes = {r.feature.name: _scene(r) for r in results}
        rows = coverage([r.feature for r in results], scenes)
        ordered = sorted(results, key=lambda r: r.passed)  # failures first, each in matrix order
        features = "\n".join(_row(r, scenes[r.feature.name], work) for r in ordered)
        page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1">
<title>wrt feature matrix</title><style>{STYLE}</style></head>
<body>
{_summary(results, device, total_s, rows)}
<table id="matrix"><tbody>
{features}
</tbody></table>
{_coverage_section(rows, results)}
<div id="viewer" hidden><figure><img id="viewer-image" alt="">
<figcaption id="viewer-caption"></figcaption></figure></div>
<script>
const PAIRS = {json.dumps(PAIRS)};{SCRIPT}</script>
</body></html>
"""
        write_atomic(os.path.join(work, "index.html"), page)
    return os.path.join(folder, "index.html")
