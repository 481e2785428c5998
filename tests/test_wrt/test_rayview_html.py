"""`wrt rays --html`: one self-contained interactive page (wrt/rayhtml.py), loaded in headless Chromium.

The page must open from the file alone with no network, draw the ray trees (pixels in the ray
kinds' colours on a canvas, not a blank one), and turn and zoom under the mouse. Its data must be
the recording's. The write is atomic and checked like the PNG's and the multiblock's.
"""

from __future__ import annotations

import base64
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import EXAMPLES
from skimage.io import imread
from wrt.kernels.record import CAMERA

import wrt
from wrt import rayhtml, rayview
from wrt.cli import main
from wrt.rays import trace_rays

REFRACTION = EXAMPLES / "whitted" / "refraction.toml"
README_PIXELS = [(130, 200), (345, 125)]  # the README's example
# headless, no GPU: WebGL runs on SwiftShader (opted in, as Chromium asks); every host name fails
# to resolve, so that a page reaching for the network could not get anything
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--allow-file-access-from-files",
    "--host-resolver-rules=MAP * ~NOTFOUND",
    "--virtual-time-budget=60000",
]


def find_chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.fail("headless Chromium is needed for the ray view test: apt-get install chromium (.ci/run installs it)")


def chromium(*args, timeout=120):
    return subprocess.run([find_chromium(), *CHROMIUM_FLAGS, *args], capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def tree():
    return trace_rays(wrt.load_scene(REFRACTION), README_PIXELS)


@pytest.fixture(scope="module")
def page(tree, tmp_path_factory):
    """The page, alone in a folder of its own."""
    path = tmp_path_factory.mktemp("page") / "view.html"
    rayhtml.save_html(tree, str(path))
    return path


def scene_data(path: Path) -> dict:
    text = path.read_text()
    found = re.search(r'<script type="application/json" id="wrt-scene">(.*?)</script>', text, re.DOTALL)
    return json.loads(found[1])


def floats(text: str) -> np.ndarray:
    return np.frombuffer(base64.b64decode(text), dtype="<f4").reshape(-1, 3)


def test_the_page_is_one_file_with_the_recording_in_it(tree, page):
    """Nothing outside the file: no URL, no linked script, style, image or font; and the data is the
    recording's: every segment a line in its kind's colour, every hit a ball, the start view that of
    the PNG."""
    text = page.read_text()
    assert len(text.encode()) < 400_000  # the README example: about 100 kB
    code = re.sub(r'(<script type="application/json" id="wrt-scene">).*?(</script>)', r"\1\2", text, flags=re.DOTALL)
    assert not re.search(r"(https?:|ftp:|//[a-z0-9])", code, re.IGNORECASE), "the page names a network address"
    assert not re.search(r"<(link|img|iframe|object|embed)\b|\bsrc\s*=|@import|url\(|fetch\(", code, re.IGNORECASE)
    data = scene_data(page)
    drawn = np.concatenate([floats(lines["positions"]) for lines in data["lines"]])
    ends = np.flatnonzero(~tree.escaped)
    for row in ends:  # each segment that ends is a line between its two ends
        pair = np.all(np.isclose(drawn[0::2], tree.origin[row], atol=1e-6), axis=1)
        pair &= np.all(np.isclose(drawn[1::2], tree.end[row], atol=1e-6), axis=1)
        assert pair.any(), f"segment {row} is not drawn"
    np.testing.assert_allclose(floats(data["balls"]["positions"]), tree.end[tree.hit], atol=1e-6)
    legend = dict(data["legend"])
    for kind in set(tree.kind.tolist()):
        assert legend[tree.KIND_NAMES[kind]] == rayview.KIND_COLORS[kind]
    assert "light" in legend and len(data["meshes"]) == len(tree.scene.shapes)
    camera = rayview.view_camera(tree)
    np.testing.assert_allclose(data["view"]["eye"], camera.eye)
    np.testing.assert_allclose(data["view"]["focus"], camera.focus)
    assert data["title"].startswith("refraction.toml: pixels (130, 200), (345, 125)")


def test_the_page_draws_the_ray_trees_in_headless_chromium(page):
    """A screenshot of the page: away from the title, legend and help (which are HTML, drawn even
    when WebGL draws nothing), most of the picture is drawn over the white background, and the
    camera rays' blue is there."""
    shot = page.parent / "shot.png"
    proc = chromium(f"--screenshot={shot}", "--window-size=1280,960", page.as_uri())
    assert shot.is_file(), proc.stderr[-2000:]
    pixels = imread(shot)[..., :3].astype(int)  # sRGB bytes, as on screen
    assert pixels.shape[:2] == (960, 1280)
    canvas = pixels[30:920, :1100]  # below the title, left of the legend, above the help line
    drawn = np.any(canvas < 245, axis=-1).mean()
    assert drawn > 0.3, f"only {drawn:.1%} of the picture is drawn"
    blue = np.array([int(rayview.KIND_COLORS[CAMERA][k : k + 2], 16) for k in (1, 3, 5)])
    assert (np.abs(canvas - blue).max(axis=-1) <= 24).sum() > 500, "no camera ray drawn"  # 2 rays: ~2800 px


PROBE = """<!DOCTYPE html><body><iframe id="page" src="view.html" style="width:800px;height:600px"></iframe>
<pre id="result">pending</pre><script>
const frame = document.getElementById("page");
function picture(doc) {  // the canvas as read back (the page keeps its drawing buffer), summed up
  const canvas = doc.getElementById("view"), copy = document.createElement("canvas");
  copy.width = canvas.width; copy.height = canvas.height;
  const ctx = copy.getContext("2d"); ctx.drawImage(canvas, 0, 0);
  const px = ctx.getImageData(0, 0, copy.width, copy.height).data;
  let drawn = 0; const colours = new Set();
  for (let i = 0; i < px.length; i += 4) {
    if (px[i] < 245 || px[i + 1] < 245 || px[i + 2] < 245) drawn++;
    colours.add((px[i] >> 3) * 1024 + (px[i + 1] >> 3) * 32 + (px[i + 2] >> 3));
  }
  return { px, drawn: drawn / (px.length / 4), colours: colours.size, width: copy.width };
}
function changed(a, b) {  // share of the pixels that differ
  let n = 0;
  for (let i = 0; i < a.px.length; i += 4) if (a.px[i] !== b.px[i]) n++;
  return n / (a.px.length / 4);
}
function drawnAgain(doc, since) {  // resolves once the page has drawn a frame after frame ``since``
  return new Promise((done) => {  // or after 20 s of virtual time: the result then tells that no frame came
    const poll = (left) => {
      if (Number(doc.body.dataset.frames) > since || left === 0) done(); else setTimeout(() => poll(left - 1), 50);
    };
    poll(400);
  });
}
frame.addEventListener("load", async () => {
  const win = frame.contentWindow, doc = frame.contentDocument, canvas = doc.getElementById("view");
  await drawnAgain(doc, 0);
  const first = picture(doc), frames = doc.body.dataset.frames, error = doc.body.dataset.error || "";
  const at = { pointerId: 7, clientX: 300, clientY: 300, button: 0, bubbles: true };
  canvas.dispatchEvent(new win.PointerEvent("pointerdown", at));
  for (let k = 1; k <= 4; k++) {
    canvas.dispatchEvent(new win.PointerEvent("pointermove", { ...at, clientX: 300 + 30 * k }));
  }
  canvas.dispatchEvent(new win.PointerEvent("pointerup", at));
  await drawnAgain(doc, Number(frames));
  const turned = picture(doc), afterTurn = Number(doc.body.dataset.frames);
  const wheel = { deltaY: -400, clientX: 400, clientY: 300, bubbles: true, cancelable: true };
  canvas.dispatchEvent(new win.WheelEvent("wheel", wheel));
  await drawnAgain(doc, afterTurn);
  const zoomed = picture(doc), afterZoom = Number(doc.body.dataset.frames);
  document.getElementById("result").textContent = JSON.stringify({
    frames, afterTurn, afterZoom, error, resources: win.performance.getEntriesByType("resource").length,
    drawn: first.drawn, colours: first.colours, width: first.width,
    turned: changed(first, turned), zoomed: changed(turned, zoomed), zoomedDrawn: zoomed.drawn,
  });
});
</script></body>"""


def probe_result(probe: Path) -> dict:
    """What the probe page found, from the DOM headless Chromium dumps once its virtual time is spent."""
    dom = chromium("--dump-dom", probe.as_uri()).stdout
    found = re.search(r'<pre id="result">(.*?)</pre>', dom, re.DOTALL)
    assert found and found[1] != "pending", dom[-2000:]
    return json.loads(found[1].replace("&quot;", '"'))


def test_the_page_turns_and_zooms_offline(page):
    """In a frame of a probe page: the view loads nothing (no request of any kind), draws, and a
    drag turns it and the wheel zooms it (the canvas changes). A run in which the page drew no frame
    after an event within the virtual time is run again (twice at most): that is the loaded machine's
    compositor, not the page; a frame drawn and unchanged fails at once."""
    probe = page.parent / "probe.html"
    probe.write_text(PROBE)
    for _ in range(3):  # a frame that did not come is the loaded machine's; a frame unchanged is the page's
        result = probe_result(probe)
        if result["afterZoom"] > result["afterTurn"] > int(result["frames"]):
            break
    assert result["afterZoom"] > result["afterTurn"] > int(result["frames"]), (
        f"no frame after the drag or wheel: {result}"
    )
    assert result["error"] == "" and int(result["frames"]) >= 1, result
    assert result["resources"] == 0, result  # no file, image, font or script fetched
    assert result["width"] == 800 and result["drawn"] > 0.3 and result["colours"] > 50, result
    assert result["turned"] > 0.05, result  # a drag of 120 px turns the scene
    assert result["zoomed"] > 0.05 and result["zoomedDrawn"] > 0.3, result


def test_html_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "view.html"
    args = ["rays", str(REFRACTION), "--pixel", "150", "200", "--pixel", "300", "150"]
    assert main([*args, "--html", str(out), "--view", "30", "40"]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    data = scene_data(out)
    camera = rayview.view_camera(trace_rays(wrt.load_scene(REFRACTION), [(150, 200), (300, 150)]), (30, 40))
    np.testing.assert_allclose(data["view"]["eye"], camera.eye, rtol=1e-6)


@pytest.mark.parametrize(
    "name, message",
    [
        ("view.png", "--html writes a web page, use a .html name"),
        ("missing/view.html", "does not exist"),
    ],
)
def test_html_bad_output_is_one_line_and_exit_2(tmp_path, capsys, name, message):
    out = tmp_path / name
    assert main(["rays", str(REFRACTION), "--pixel", "150", "200", "--html", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and err.startswith("wrt: error: "), err
    assert not out.exists()


def test_html_on_a_full_disk_keeps_the_old_page(full_disk, capsys):
    """Written once while there is room, then refused on the full disk: one line, exit 2, the old
    page byte for byte, no temporary file left."""
    out = full_disk.path / "view.html"
    args = ["rays", str(REFRACTION), "--pixel", "150", "200", "--html", str(out)]
    assert main(args) == 0
    capsys.readouterr()
    before = out.read_bytes()
    full_disk.fill()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("wrt: error: ") and err.count("\n") == 1 and str(out) in err, err
    assert out.read_bytes() == before
    assert sorted(p.name for p in full_disk.path.iterdir() if p.name != ".filler") == ["view.html"]
