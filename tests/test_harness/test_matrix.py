"""The visual regression harness (harness/): the feature matrix collected by pytest, its
sensitivity (every deliberately wrong variant fails), reference handling and `wrt compare` (the
HTML report in a real headless browser: test_report.py)."""

import json
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
import wrt_harness.references as references
from conftest import copy_references
from wrt_harness.matrix import load_features, select
from wrt_harness.report import write_report
from wrt_harness.run import evaluate

from wrt.cli import main
from wrt.errors import WrtError
from wrt.imageio import write_image

FEATURES = load_features()


def describe(r) -> str:
    lines = [
        f"{r.feature.name}: SSIM {r.ssim:.4f} (threshold {r.ssim_threshold:.4f}), geometry SSIM {r.geometry_ssim:.4f}"
    ]
    if r.z is not None:
        lines.append(f"Z-test: min p {r.z.min_p:.2e}, {r.z.rejected} rejected at level {r.z.threshold:.1e}")
    return "\n".join(lines + r.failures)


@pytest.mark.matrix
@pytest.mark.parametrize("feature", FEATURES, ids=[f.name for f in FEATURES])
def test_feature(feature, tmp_path):
    """One matrix entry, exactly as `wrt matrix NAME` scores it."""
    result = evaluate(feature)
    if not result.passed:
        page = write_report([result], str(tmp_path / "report"), "cpu")
        pytest.fail(f"{describe(result)}\nreport: {page}")


@pytest.mark.matrix
@pytest.mark.parametrize("feature", FEATURES, ids=[f.name for f in FEATURES])
def test_wrong_variant_fails(feature):
    """The harness is sensitive: the feature's deliberately wrong variant scores below its thresholds."""
    assert feature.wrong.get("description"), "every feature needs a wrong variant"
    result = evaluate(feature, wrong=True)
    assert not result.passed, f"wrong variant ({feature.wrong['description']}) still passes:\n{describe(result)}"


def test_missing_corrupt_and_stale_references_name_the_fix(tmp_path, monkeypatch, capsys):
    folder = copy_references(tmp_path, monkeypatch, ["raycast_sphere", "raycast_triangle"])
    feature = select(FEATURES, ["raycast_sphere"])[0]
    os.remove(folder / "raycast_sphere.exr")
    assert main(["matrix", "raycast_sphere"]) == 2
    assert "run: wrt refs regenerate raycast_sphere" in capsys.readouterr().err
    (folder / "raycast_sphere.exr").write_bytes(b"not an exr at all")
    with pytest.raises(references.ReferenceError, match="unreadable.*wrt refs regenerate raycast_sphere"):
        references.load_reference(feature)
    # a reference made from another scene: same size, other hash
    tri = select(FEATURES, ["raycast_triangle"])[0]
    shutil.copy(folder / "raycast_triangle.exr", folder / "raycast_sphere.exr")
    with pytest.raises(references.ReferenceError, match="scene hash differs"):
        references.load_reference(feature)
    # a calibration that belongs to another image
    data = json.loads((folder / "raycast_triangle.json").read_text())
    data["reference_sha256"] = "0" * 64
    (folder / "raycast_triangle.json").write_text(json.dumps(data))
    with pytest.raises(references.ReferenceError, match="calibration belongs to another"):
        references.load_reference(tri)


def test_unknown_feature_exits_2(capsys):
    assert main(["matrix", "no_such_feature"]) == 2
    assert "unknown feature 'no_such_feature'" in capsys.readouterr().err


def test_regenerate_writes_reproducible_calibrated_references(tmp_path, monkeypatch, capsys):
    folder = copy_references(tmp_path, monkeypatch, ["antialiasing"])
    before = (folder / "antialiasing.exr").read_bytes()
    assert main(["refs", "regenerate", "antialiasing", "--spp", "256"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"antialiasing: 256 spp, SSIM old vs new 0\.99\d+", out), out
    after = references.load_reference(select(FEATURES, ["antialiasing"])[0])
    assert after.spp == 256 and (folder / "antialiasing.exr").read_bytes() != before
    assert after.calibration["ssim_threshold"] < min(after.calibration["ssim"])
    assert sorted(os.listdir(folder)) == ["antialiasing.exr", "antialiasing.json", "antialiasing.png"]  # no temp files


def test_interrupted_regeneration_keeps_the_old_reference(tmp_path, monkeypatch):
    folder = copy_references(tmp_path, monkeypatch, ["raycast_sphere"])
    before = {p.name: p.read_bytes() for p in folder.iterdir()}

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("wrt.imageio.os.replace", interrupted)  # Ctrl-C just before the rename
    assert main(["refs", "regenerate", "raycast_sphere"]) == 130
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_a_reference_that_does_not_reproduce_is_refused(tmp_path, monkeypatch):
    folder = copy_references(tmp_path, monkeypatch, ["antialiasing"])
    before = (folder / "antialiasing.exr").read_bytes()
    real = references.render_feature

    def biased(feature, spp=None, seed=None, **kwargs):  # the later seeds render a 3% brighter image
        result = real(feature, spp=spp, seed=seed, **kwargs)
        if seed is not None and seed >= references.REFERENCE_SEED + references.BATCHES // 2:
            result.rgb = result.rgb * 1.03
        return result

    monkeypatch.setattr(references, "render_feature", biased)
    with pytest.raises(WrtError, match="does not reproduce"):
        references.render_reference(select(FEATURES, ["antialiasing"])[0], spp=64)
    assert (folder / "antialiasing.exr").read_bytes() == before


def test_compare(tmp_path, capsys):
    a = np.random.default_rng(0).uniform(0, 1, (32, 32, 3)).astype(np.float32)
    write_image(str(tmp_path / "a.exr"), a)
    write_image(str(tmp_path / "b.exr"), a * 0.5)
    assert main(["compare", str(tmp_path / "a.exr"), str(tmp_path / "a.exr"), "--threshold", "0.999"]) == 0
    assert "SSIM 1.000000" in capsys.readouterr().out
    assert main(["compare", str(tmp_path / "a.exr"), str(tmp_path / "b.exr"), "--threshold", "0.99"]) == 1
    assert main(["compare", str(tmp_path / "a.exr"), str(tmp_path / "missing.exr")]) == 2


def test_compare_exits_1_on_a_failing_z_test(tmp_path, capsys):
    """With a reference variance and both spp, a mean shifted beyond the noise fails, threshold or not."""
    rng = np.random.default_rng(1)
    reference = rng.uniform(0.2, 1.0, (32, 32, 3)).astype(np.float32)
    variance = np.full_like(reference, 0.01)
    write_image(str(tmp_path / "ref.exr"), reference, aovs={"variance": variance}, metadata={"spp": 1024})
    noisy = reference + rng.normal(size=reference.shape).astype(np.float32) * 0.1 / 4  # 16 spp of variance 0.01
    write_image(str(tmp_path / "ok.exr"), noisy, metadata={"spp": 16})
    write_image(str(tmp_path / "bright.exr"), noisy * 1.2, metadata={"spp": 16})
    assert main(["compare", str(tmp_path / "ok.exr"), str(tmp_path / "ref.exr")]) == 0
    assert "Z-test pass" in capsys.readouterr().out
    assert main(["compare", str(tmp_path / "bright.exr"), str(tmp_path / "ref.exr")]) == 1
    assert "Z-test FAIL" in capsys.readouterr().out


def test_the_harness_has_a_command_of_its_own(tmp_path):
    """``python -m wrt_harness`` (``wrt-harness``) runs the same verbs without ``wrt``."""
    write_image(str(tmp_path / "a.exr"), np.full((8, 8, 3), 0.5, np.float32))
    same = subprocess.run(
        [sys.executable, "-m", "wrt_harness", "compare", str(tmp_path / "a.exr"), str(tmp_path / "a.exr")],
        capture_output=True,
        text=True,
    )
    assert same.returncode == 0 and "SSIM 1.000000" in same.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "wrt_harness", "matrix", "no_such_feature"], capture_output=True, text=True
    )
    assert bad.returncode == 2 and bad.stderr.startswith("wrt-harness: error:") and "no_such_feature" in bad.stderr


def test_regenerate_failed_only_touches_broken_references(tmp_path, monkeypatch, capsys):
    folder = copy_references(tmp_path, monkeypatch, ["raycast_sphere", "raycast_triangle"])
    good = (folder / "raycast_triangle.exr").read_bytes()
    os.remove(folder / "raycast_sphere.exr")
    assert main(["refs", "regenerate", "raycast_sphere", "raycast_triangle", "--failed"]) == 0
    out = capsys.readouterr().out
    assert "raycast_sphere: 1 spp, new reference" in out and "raycast_triangle" not in out
    assert (folder / "raycast_triangle.exr").read_bytes() == good
    assert main(["matrix", "raycast_sphere", "raycast_triangle", "--jobs", "2"]) == 0
