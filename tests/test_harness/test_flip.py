"""FLIP beside SSIM (harness/flip.py): the package's numbers, its calibration, its part in the
matrix (a perturbed render fails by FLIP, a FLIP miss is re-rendered at 4x spp like an SSIM miss),
a calibration without a FLIP threshold, and ``wrt compare --metric flip``."""

import json

import flip_evaluator
import numpy as np
import pytest
import wrt_harness.references as references
import wrt_harness.run as run
from conftest import copy_references
from wrt_harness.flip import ACES_TARGET, FLIP_CRITERION, check_flip_threshold, error_map_image, flip
from wrt_harness.matrix import load_features, select
from wrt_harness.score import srgb_encode

from wrt.cli import main
from wrt.errors import WrtError
from wrt.imageio import write_image

FEATURES = load_features()


def pair(seed=0, size=(24, 32)):
    """An HDR reference (values up to 4, above the tone map's clip) and a noisy image of it."""
    rng = np.random.default_rng(seed)
    reference = rng.uniform(0.0, 4.0, (*size, 3)).astype(np.float32)
    image = (reference * rng.uniform(0.8, 1.2, reference.shape)).astype(np.float32)
    return image, reference


def edit_calibration(folder, name, change):
    path = folder / f"{name}.json"
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))
    return path


def test_flip_of_an_image_against_itself_is_zero():
    _, reference = pair()
    same = flip(reference, reference)
    assert same.hdr == 0.0 and same.ldr == 0.0
    assert not same.hdr_map.any() and not same.ldr_map.any()


def test_flip_is_the_packages_flip():
    """HDR-FLIP of the linear values and LDR-FLIP of the sRGB tone-mapped ones, as
    ``flip_evaluator.evaluate`` with its default parameters gives them (reference first)."""
    image, reference = pair()
    ours = flip(image, reference)
    hdr_map, hdr, _ = flip_evaluator.evaluate(reference, image, "HDR", applyMagma=False)
    ldr_map, ldr, _ = flip_evaluator.evaluate(
        srgb_encode(reference).astype(np.float32), srgb_encode(image).astype(np.float32), "LDR", applyMagma=False
    )
    assert ours.hdr == pytest.approx(hdr, rel=1e-6) and ours.ldr == pytest.approx(ldr, rel=1e-6)
    assert 0.01 < ours.ldr < ours.hdr < 1.0  # the HDR one sees the values above 1 the tone map clips
    np.testing.assert_allclose(ours.hdr_map, hdr_map[..., 0])
    np.testing.assert_allclose(ours.ldr_map, ldr_map[..., 0])
    assert ours.hdr_map.mean() == pytest.approx(ours.hdr, rel=1e-4)
    # the report's map: the package's magma colours of the same per-pixel HDR-FLIP
    magma, _, _ = flip_evaluator.evaluate(reference, image, "HDR")
    assert FLIP_CRITERION == "hdr"
    np.testing.assert_allclose(srgb_encode(error_map_image(image, reference)), magma, atol=1e-5)


def test_hdr_flip_sees_what_the_tone_map_clips():
    """A highlight at 2 rendered at 4: the same white in sRGB (SSIM and LDR-FLIP see nothing)."""
    reference = np.full((32, 32, 3), 0.2, np.float32)
    reference[8:16, 8:16] = 2.0
    image = reference.copy()
    image[8:16, 8:16] = 4.0
    scores = flip(image, reference)
    assert scores.ldr == 0.0 and scores.hdr > 0.01


def test_flat_and_black_references_are_scored_not_fatal():
    """The package ends the process (exit 255) when a black, constant or nearly black reference
    gives it an empty or reversed exposure range; ``flip`` sets the range there."""
    black = np.zeros((16, 16, 3), np.float32)
    grey = np.full((16, 16, 3), 0.3, np.float32)
    assert flip(black, black).hdr == 0.0
    assert 0.5 < flip(grey, black).hdr <= 1.0 and 0.5 < flip(black, grey).hdr <= 1.0
    faint = np.full((16, 16, 3), 1e-10, np.float32)
    spot = faint.copy()
    spot[4, 4] = 1e-9
    assert 0.0 < flip(spot, faint).hdr < 1.0 and 0.0 < flip(faint, spot).hdr < 1.0
    # the package's own range for a constant reference it can handle: one exposure, log2(ACES_TARGET / Y)
    _, _, used = flip_evaluator.evaluate(grey, grey, "HDR", applyMagma=False)
    assert used["startExposure"] == pytest.approx(np.log2(ACES_TARGET / 0.3), abs=1e-5)
    spot = grey.copy()
    spot[4, 4] = 0.6
    _, expected, _ = flip_evaluator.evaluate(grey, spot, "HDR", applyMagma=False)
    assert flip(spot, grey).hdr == pytest.approx(expected, rel=1e-3)  # its exposure is float32: 4e-7 off


@pytest.mark.parametrize("value", [float("nan"), float("inf"), -0.01, True, "0.1", None])
def test_a_flip_threshold_must_be_a_finite_number_at_least_0(value):
    with pytest.raises(WrtError, match=r"x\.json: flip_threshold = .*finite number >= 0"):
        check_flip_threshold(value, "x.json: flip_threshold")
    assert check_flip_threshold(0, "t") == 0.0 and check_flip_threshold(0.05, "t") == 0.05


def test_calibration_sets_the_flip_threshold_above_the_spread(monkeypatch):
    """threshold = max(FLIP) + max(0.002, 3 std(FLIP)) over the calibration seeds, SSIM's as before."""
    feature = select(FEATURES, ["cornell_box_path"])[0]
    reference = references.load_reference(feature)
    gains = dict(zip(references.CALIBRATION_SEEDS, (1.00, 1.01, 1.02, 1.03, 1.05, 1.08)))
    # the test renders' gains by seed; the re-renders the calibration pools them with are exact
    fake = lambda f, seeds, **kw: [reference.rgb * gains.get(s, 1.0) for s in seeds]  # noqa: E731
    monkeypatch.setattr(references, "render_images", fake)
    cal = references.calibrate(feature, reference)
    hdr = [flip(reference.rgb * g, reference.rgb).hdr for g in gains.values()]
    assert cal["hdr_flip"] == pytest.approx(hdr) and cal["flip_criterion"] == "hdr"
    assert cal["flip_threshold"] == pytest.approx(max(hdr) + max(0.002, 3 * np.std(hdr, ddof=1)))
    assert 3 * np.std(hdr, ddof=1) > 0.002  # the spread, not the floor, set it
    assert cal["ssim_threshold"] < min(cal["ssim"]) and len(cal["ldr_flip"]) == 6


def test_the_stored_flip_thresholds_are_calibrated():
    """Every feature's calibration holds its FLIP threshold, above each calibration seed's FLIP."""
    for feature in FEATURES:
        cal = references.load_reference(feature).calibration
        flips = cal[f"{cal['flip_criterion']}_flip"]
        assert max(flips) + 0.002 <= cal["flip_threshold"] + 1e-12, feature.name


def test_a_perturbed_render_fails_by_flip(tmp_path, monkeypatch, capsys):
    """A deterministic feature whose render has a bright square (an emitter 5 x too bright)."""
    name = "raycast_sphere"
    copy_references(tmp_path, monkeypatch, [name])
    real = run.render_feature

    def perturbed(*args, **kwargs):
        result = real(*args, **kwargs)
        result.rgb = result.rgb.copy()
        result.rgb[40:48, 40:48] *= 5.0
        return result

    monkeypatch.setattr(run, "render_feature", perturbed)
    result = run.evaluate(select(FEATURES, [name])[0])
    assert not result.passed and "flip" in result.failed_checks, result.failures
    assert result.flip.hdr > result.flip_threshold
    assert any(f.startswith("HDR-FLIP ") and "> threshold" in f for f in result.failures), result.failures
    assert main(["matrix", name]) == 1
    assert "FLIP " in capsys.readouterr().out


def test_a_flip_miss_is_rerendered_at_4x_spp(tmp_path, monkeypatch):
    """A stochastic feature whose FLIP misses (here: its thresholds set to 0) is re-rendered like an
    SSIM miss, and scored by the re-render against the re-render's own threshold."""
    name = "antialiasing"
    feature = select(FEATURES, [name])[0]
    folder = copy_references(tmp_path, monkeypatch, [name])
    reference = references.load_reference(feature)
    ok = run.score_render(feature, reference.rgb, feature.spp, reference, -1.0, 0.0)[-1]
    assert ok  # the reference scores FLIP 0 against itself: a threshold of 0 is met
    edit_calibration(folder, name, lambda d: d.update(flip_threshold=0.0, rerender_flip_threshold=0.0))
    spps = []
    real = run.render_feature

    def recorded(f, spp=None, seed=None, **kwargs):
        result = real(f, spp=spp, seed=seed, **kwargs)
        spps.append(result.spp)
        return result

    monkeypatch.setattr(run, "render_feature", recorded)
    result = run.evaluate(feature)
    assert result.rerendered and spps[:2] == [feature.spp, 4 * feature.spp]
    assert result.failed_checks == ["flip"], result.failures
    assert result.flip.hdr == flip(result.images["render"], reference.rgb).hdr > 0.0


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d.pop("flip_threshold"), "missing key 'flip_threshold'"),
        (lambda d: d.update(flip_threshold=-0.5), "flip_threshold = -0.5: must be a finite number >= 0"),
        (lambda d: d.update(flip_threshold=float("nan")), "flip_threshold = nan: must be a finite number >= 0"),
    ],
    ids=["missing", "negative", "nan"],
)
def test_a_calibration_without_a_usable_flip_threshold_names_the_fix(tmp_path, monkeypatch, capsys, change, message):
    name = "raycast_sphere"
    folder = copy_references(tmp_path, monkeypatch, [name])
    path = edit_calibration(folder, name, change)
    assert main(["matrix", name]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err and message in err, err
    assert err.rstrip().endswith(f"run: wrt refs calibrate {name}"), err


def test_compare_metric_flip(tmp_path, capsys):
    image, reference = pair()
    a, b = str(tmp_path / "a.exr"), str(tmp_path / "b.exr")
    write_image(a, image)
    write_image(b, reference)
    expected = flip(image, reference)
    assert main(["compare", b, b, "--metric", "flip", "--threshold", "0"]) == 0
    assert "HDR-FLIP 0.000000" in capsys.readouterr().out
    assert main(["compare", a, b, "--metric", "flip", "--threshold", str(expected.hdr + 0.001)]) == 0
    out = capsys.readouterr().out
    assert f"HDR-FLIP {expected.hdr:.6f}" in out and f"LDR-FLIP {expected.ldr:.6f}" in out and "SSIM" not in out
    assert main(["compare", a, b, "--metric", "flip", "--threshold", str(expected.hdr - 0.001)]) == 1
    assert f"FAIL: HDR-FLIP {expected.hdr:.6f} >" in capsys.readouterr().out
    assert main(["compare", a, b]) == 0  # the default metric is SSIM, as before
    out = capsys.readouterr().out
    assert out.startswith("SSIM ") and "FLIP" not in out


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "-0.1"])
def test_compare_refuses_a_flip_threshold_that_is_not_finite_or_negative(tmp_path, capsys, value):
    a = str(tmp_path / "a.exr")
    write_image(a, pair()[1])
    assert main(["compare", a, a, "--metric", "flip", f"--threshold={value}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wrt: error: --threshold = ") and err.count("\n") == 1, err
    assert "finite number >= 0" in err, err


def test_compare_metric_flip_refuses_bad_input(tmp_path, capsys):
    a, b, holed = (str(tmp_path / n) for n in ("a.exr", "b.exr", "holed.exr"))
    write_image(a, np.full((8, 9, 3), 0.5, np.float32))
    write_image(b, np.full((9, 8, 3), 0.5, np.float32))
    rgb = np.full((8, 9, 3), 0.5, np.float32)
    rgb[2, 3] = np.nan
    write_image(holed, rgb)
    for args, fragment in (
        ([a, b], "9x8"),
        ([a, holed], "NaN"),
        ([a, str(tmp_path / "missing.exr")], "missing.exr"),
    ):
        assert main(["compare", *args, "--metric", "flip"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("wrt: error: ") and err.count("\n") == 1 and fragment in err, err
    with pytest.raises(SystemExit) as exit:
        main(["compare", a, a, "--metric", "psnr"])
    assert exit.value.code == 2 and "invalid choice: 'psnr'" in capsys.readouterr().err
    small = str(tmp_path / "small.exr")  # FLIP has no window: a 5x5 image is scored
    write_image(small, np.full((5, 5, 3), 0.5, np.float32))
    assert main(["compare", small, small, "--metric", "flip"]) == 0


def test_a_rerender_is_scored_against_thresholds_calibrated_for_it(tmp_path, monkeypatch):
    """A 5x pooled re-render is less noisy than the render it stands in for: at the 1x thresholds
    a fault often scored better than sound code at baseline. The re-render's own thresholds
    (calibrated on pooled renders) are tighter, and they are the ones it is held to."""
    name = "soft_shadows"
    feature = select(FEATURES, [name])[0]
    reference = references.load_reference(feature)
    cal = reference.calibration
    assert cal["rerender_ssim_threshold"] > cal["ssim_threshold"] + 0.05
    assert cal["rerender_flip_threshold"] < cal["flip_threshold"]
    assert cal["rerender_spp"] == 5 * feature.spp
    folder = copy_references(tmp_path, monkeypatch, [name])
    edit_calibration(folder, name, lambda d: d.update(ssim_threshold=1.0))  # the 1x render misses
    result = run.evaluate(feature)
    assert result.rerendered and result.passed, result.failures
    assert result.ssim_threshold == cal["rerender_ssim_threshold"]  # the re-render's, not 1.0
    edit_calibration(folder, name, lambda d: d.update(rerender_ssim_threshold=1.0))
    result = run.evaluate(feature)
    assert result.rerendered and result.failed_checks == ["ssim"], result.failures


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d.pop("rerender_ssim_threshold"), "missing key 'rerender_ssim_threshold'"),
        (lambda d: d.pop("rerender_flip_threshold"), "missing key 'rerender_flip_threshold'"),
        (lambda d: d.update(rerender_flip_threshold=-1), "rerender_flip_threshold = -1: must be a finite number >= 0"),
    ],
    ids=["no-ssim", "no-flip", "negative"],
)
def test_a_stochastic_calibration_without_its_rerender_thresholds_names_the_fix(
    tmp_path, monkeypatch, capsys, change, message
):
    """A calibration made before the re-render had thresholds of its own is refused, naming the fix."""
    name = "antialiasing"
    folder = copy_references(tmp_path, monkeypatch, [name])
    path = edit_calibration(folder, name, change)
    assert main(["matrix", name]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err and message in err, err
    assert err.rstrip().endswith(f"run: wrt refs calibrate {name}"), err
