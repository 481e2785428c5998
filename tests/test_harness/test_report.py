"""The matrix's HTML report (harness/report.py) in a real headless browser, at 1280 and 1920 px:
no sideways scrolling, every image decoded, the summary on top, failures first, the scores beside
or under the images, the images enlarged on click and flipped in place; and the page's contract:
one static page and its PNGs, nothing fetched from elsewhere, written only where an earlier
report was (``wrt.files.report_folder``)."""

import html
import json
import os
import re
import shutil
import subprocess

import numpy as np
import pytest
from wrt_harness.coverage import coverage
from wrt_harness.matrix import load_features, select
from wrt_harness.report import PICTURES, write_report
from wrt_harness.run import evaluate

from wrt.errors import WrtError
from wrt.imageio import read_image

WIDTHS = (1280, 1920)
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--allow-file-access-from-files"]


def find_chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.fail("headless Chromium is needed for the report test: apt-get install chromium (.ci/run installs it)")


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A report of a passing feature and a failing one (the refraction's wrong variant: every
    stochastic score on the page), given in that order: ``(page, [good, bad])``."""
    features = load_features()
    good = evaluate(select(features, ["raycast_triangle"])[0])
    bad = evaluate(select(features, ["refraction"])[0], wrong=True)
    assert good.passed and not bad.passed
    folder = tmp_path_factory.mktemp("report") / "report"
    return write_report([good, bad], str(folder), "cpu", total_s=12.5), [good, bad]


# Run in a page that holds the report in an iframe per width (each its own viewport), then writes
# what it measured into <pre id="result"> for --dump-dom. In the first frame it drives the viewer:
# a click on the first row's render, a click on the enlarged image, space, an arrow key, Escape.
PROBE = """<!DOCTYPE html><body style="margin: 0">%s<pre id="result"></pre><script>
window.addEventListener('load', () => {
  const frames = [...document.querySelectorAll('iframe')].map((frame) => {
    const doc = frame.contentDocument, win = frame.contentWindow, root = doc.documentElement;
    const rows = [...doc.querySelectorAll('#matrix > tbody > tr')].map((row) => {
      const images = row.querySelector('td.images').getBoundingClientRect();
      const scores = row.querySelector('td.scores').getBoundingClientRect();
      return {id: row.id, status: row.className, height: row.getBoundingClientRect().height,
              images_height: images.height, scores_width: scores.width,
              beside: scores.left >= images.right - 1, under: scores.top >= images.bottom - 1};
    });
    const images = [...doc.querySelectorAll('img[data-kind]')].map(
      (i) => ({src: i.getAttribute('src'), width: i.naturalWidth, height: i.naturalHeight, complete: i.complete}));
    const out = {viewport: win.innerWidth, client_width: root.clientWidth, scroll_width: root.scrollWidth,
                 summary: doc.querySelector('#summary').textContent,
                 failed: [...doc.querySelectorAll('#failed a')].map((a) => a.getAttribute('href')),
                 rows: rows, images: images};
    if (frame.id === 'w0') {
      const viewer = doc.getElementById('viewer'), big = doc.getElementById('viewer-image');
      const state = () => ({hidden: viewer.hidden, src: big.getAttribute('src'), caption: doc.getElementById(
        'viewer-caption').textContent, width: big.getBoundingClientRect().width});
      const key = (k) => doc.dispatchEvent(new win.KeyboardEvent('keydown', {key: k, bubbles: true}));
      const thumbnail = doc.querySelector('#matrix tr img[data-kind=render]');
      const steps = [state()];
      thumbnail.click(); steps.push(state());
      big.click(); steps.push(state());
      key(' '); steps.push(state());
      key('ArrowRight'); steps.push(state());
      key('Escape'); steps.push(state());
      out.viewer = {thumbnail_width: thumbnail.getBoundingClientRect().width, steps: steps};
    }
    return out;
  });
  document.getElementById('result').textContent = JSON.stringify(frames);
});
</script></body>"""


@pytest.fixture(scope="module")
def measured(report, tmp_path_factory):
    """What the probe page measured in the report at each of ``WIDTHS``, by width."""
    page, _ = report
    frames = "".join(
        f'<iframe id="w{i}" src="file://{page}" width="{w}" height="900" style="border: 0; display: block"></iframe>'
        for i, w in enumerate(WIDTHS)
    )
    probe = tmp_path_factory.mktemp("probe") / "probe.html"
    probe.write_text(PROBE % frames)
    dom = subprocess.run(
        [find_chromium(), *FLAGS, "--window-size=2000,1000", "--dump-dom", f"file://{probe}"],
        capture_output=True,
        text=True,
        timeout=120,
    ).stdout
    found = re.search(r'<pre id="result">(.*?)</pre>', dom, re.S)
    assert found and found.group(1), dom[-2000:]
    return dict(zip(WIDTHS, json.loads(html.unescape(found.group(1)))))


@pytest.mark.parametrize("width", WIDTHS)
def test_the_report_fits_the_screen(measured, width):
    """No sideways scrolling at 1280 and 1920 px; every image decoded; the scores sit beside or
    under the images, not in a tall narrow strip: a row is less than twice its images' height."""
    m = measured[width]
    assert m["viewport"] == width
    assert m["scroll_width"] <= m["client_width"], m
    assert len(m["images"]) == 2 * len(PICTURES)
    assert all(i["complete"] and i["width"] > 0 and i["height"] > 0 for i in m["images"]), m["images"]
    for row in m["rows"]:
        assert row["beside"] or row["under"], row
        assert row["scores_width"] >= 300, row
        assert row["height"] < 2 * row["images_height"], row
    assert [row["under"] for row in m["rows"]] == [width < 1600] * 2  # beside the images on a wide screen


def test_the_summary_and_failures_come_first(measured, report):
    """The summary names the counts, the failed features (linked to their rows), the total time and
    the machine; the failed row comes before the passing one, though the matrix ran it second."""
    m = measured[1280]
    summary = " ".join(m["summary"].split())
    assert "wrt feature matrix: 1 of 2 pass" in summary and "1 failed" in summary and "1 passed" in summary
    assert "total time 12.5 s" in summary and "device cpu" in summary and "cores" in summary
    assert m["failed"] == ["#refraction"]
    assert [(row["status"], row["id"]) for row in m["rows"]] == [("fail", "refraction"), ("pass", "raycast_triangle")]
    # each row's FLIP map is decoded at its render's size
    _, (good, bad) = report
    flips = [(i["width"], i["height"]) for i in m["images"] if i["src"].endswith(".flip.png")]
    assert flips == [(r.feature.width, r.feature.height) for r in (bad, good)]


def test_a_click_enlarges_an_image_and_flips_it_with_its_reference(measured):
    """A click on a render opens it enlarged; a click on it, or space, flips it in place between
    render and reference; an arrow key steps to the next image of the row; Escape closes it."""
    viewer = measured[1280]["viewer"]
    closed, opened, flipped, back, stepped, shut = viewer["steps"]
    assert closed["hidden"] and shut["hidden"]
    assert not opened["hidden"] and opened["src"] == "refraction.render.png"
    assert opened["width"] > 4 * viewer["thumbnail_width"], viewer
    assert "refraction: render" in opened["caption"] and "reference" in opened["caption"]
    assert flipped["src"] == "refraction.reference.png" and flipped["width"] == opened["width"]
    assert back["src"] == "refraction.render.png"
    assert stepped["src"] == "refraction.diff.png"


def test_the_page_draws_its_images(report, tmp_path):
    """A screenshot of the page at 1280 px is drawn: its images and colours, not a blank page."""
    page, _ = report
    shot = tmp_path / "shot.png"
    subprocess.run(
        [find_chromium(), *FLAGS, f"--screenshot={shot}", "--window-size=1280,900", f"file://{page}"],
        capture_output=True,
        timeout=120,
    )
    pixels = read_image(str(shot)).rgb
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 50


def test_the_page_is_static_and_self_contained(report):
    """One page and its PNGs: every src names a PNG of the report's folder, nothing is fetched
    from a server, and the rows are the ``<tr class=STATUS id=NAME>`` that tools read."""
    page, _ = report
    text = open(page).read()
    folder = os.path.dirname(page)
    sources = re.findall(r'src="([^"]*)"', text)
    assert sources and all(os.path.isfile(os.path.join(folder, s)) and s.endswith(".png") for s in sources)
    assert not re.search(r"(src|href)=\"[a-z]+:|<link|@import|url\(", text)
    assert re.findall(r'<tr class="(pass|fail)" id="(\w+)"', text) == [
        ("fail", "refraction"),
        ("pass", "raycast_triangle"),
    ]


def test_the_report_has_the_coverage_table(report):
    """The coverage table of the report's features: a row per kind, its features linked, the
    kinds no feature of the report exercises marked."""
    page, results = report
    text = open(page).read()
    section = text[text.index('<section id="coverage">') :]
    rows = coverage([r.feature for r in results])
    cells = re.findall(r"<tr( class=missing)?><td>([^<]*)</td><td>([^<]*)</td><td>(.*?)</td></tr>", section)
    assert [(html.unescape(g), html.unescape(k)) for _, g, k, _ in cells] == [(r.group, r.kind) for r in rows]
    for (missing, _, _, features), row in zip(cells, rows):
        assert bool(missing) == (not row.features)
        assert re.findall(r'href="#(\w+)"', features) == list(row.features)


def test_a_report_replaces_only_a_report(report, tmp_path):
    """The writer's contract: a folder holding anything but an earlier report is refused, untouched."""
    _, results = report
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "mine.txt").write_text("mine")
    with pytest.raises(WrtError):
        write_report(results[:1], str(notes), "cpu")
    assert os.listdir(notes) == ["mine.txt"]
