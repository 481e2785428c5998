"""The harness never passes silently on corrupt numbers: corrupt references, thresholds that turn a
check off, non-finite pixels, malformed calibration files and images too small to score are refused
(one line ``wrt: error: ...`` naming the file, the key and the value; exit code 2) or, for a render
with non-finite pixels, count as a failure (exit code 1)."""

import json
import re
import shutil

import numpy as np
import pytest
import wrt_harness.references as references
import wrt_harness.run as run
from conftest import copy_references, one_feature_file
from wrt_harness.matrix import load_features, select

from wrt.cli import main
from wrt.errors import WrtError
from wrt.imageio import read_image, write_image

FEATURE = "raycast_sphere"  # deterministic and fast: the matrix renders it in milliseconds


def rewrite_reference(folder, name=FEATURE, rgb=None, variance=None):
    """Rewrite the reference EXR with other pixels (same metadata) and re-sign its calibration, so
    that nothing but the numbers is wrong."""
    exr = folder / f"{name}.exr"
    image = read_image(str(exr))
    rgb = image.rgb if rgb is None else rgb(image.rgb.copy())
    variance = image.aovs["variance"] if variance is None else variance(image.aovs["variance"].copy())
    # float32 RGB: a half-float write stores Inf as 65504 (wrt never writes an Inf), and these tests plant one
    write_image(str(exr), rgb, aovs={"variance": variance}, metadata=image.metadata)
    calibration = folder / f"{name}.json"
    data = json.loads(calibration.read_text())
    data["reference_sha256"] = references.file_sha256(str(exr))
    calibration.write_text(json.dumps(data))
    return exr


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("wrt: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


def set_all(value):
    def change(a):
        a[...] = value
        return a

    return change


def set_one(value):
    def change(a):
        a[3, 5, 1] = value
        return a

    return change


CORRUPTIONS = {
    "nan_variance": (dict(variance=set_all(np.nan)), r"variance.*NaN"),
    "all_nan_rgb": (dict(rgb=set_all(np.nan)), r"RGB.*NaN"),
    "one_inf_rgb": (dict(rgb=set_one(np.inf)), r"RGB.*Inf"),
    "one_negative_variance": (dict(variance=set_one(-0.5)), r"variance.*negative"),
    "one_inf_variance": (dict(variance=set_one(-np.inf)), r"variance.*Inf"),
}


@pytest.mark.parametrize("corruption", CORRUPTIONS, ids=list(CORRUPTIONS))
def test_a_corrupt_reference_is_refused_by_matrix_and_compare(tmp_path, monkeypatch, capsys, corruption):
    """Class 1: NaN variance used to skip the Z-test (an all-NaN reference passed)."""
    changes, problem = CORRUPTIONS[corruption]
    folder = copy_references(tmp_path, monkeypatch, [FEATURE])
    clean = tmp_path / "clean.exr"
    shutil.copy(folder / f"{FEATURE}.exr", clean)
    exr = rewrite_reference(folder, **changes)
    assert main(["matrix", FEATURE]) == 2
    err = one_error_line(capsys)
    assert str(exr) in err and "corrupt" in err and f"wrt refs regenerate {FEATURE}" in err
    assert re.search(problem, err), err
    assert main(["compare", str(clean), str(exr)]) == 2
    err = one_error_line(capsys)
    assert str(exr) in err and re.search(problem, err), err


THRESHOLDS = [float("-inf"), float("inf"), float("nan"), 1.5, -1.01]


@pytest.mark.parametrize("value", THRESHOLDS, ids=str)
def test_a_calibrated_threshold_out_of_range_is_refused(tmp_path, monkeypatch, capsys, value):
    """Class 2: ssim_threshold = -Infinity in the calibration turned the SSIM check off."""
    folder = copy_references(tmp_path, monkeypatch, [FEATURE])
    path = folder / f"{FEATURE}.json"
    data = json.loads(path.read_text())
    data["ssim_threshold"] = value
    path.write_text(json.dumps(data))  # json writes NaN / Infinity / -Infinity, as Python reads them
    assert main(["matrix", FEATURE]) == 2
    err = one_error_line(capsys)
    assert str(path) in err and f"ssim_threshold = {value!r}" in err and "[-1, 1]" in err, err


@pytest.mark.parametrize("value", ["-inf", "nan", "inf", "1.5", "-3"])
def test_a_geometry_threshold_out_of_range_is_refused(tmp_path, value):
    """Class 2, the feature list: geometry_threshold = -inf turned the geometry oracle off."""
    features = one_feature_file(tmp_path, f"geometry_threshold = {value}")
    with pytest.raises(WrtError) as e:
        load_features(str(features))
    message = str(e.value)
    assert str(features) in message and "geometry_threshold = " in message and "[-1, 1]" in message, message


def test_a_geometry_threshold_string_is_refused(tmp_path):
    features = one_feature_file(tmp_path, 'geometry_threshold = "0.9"')
    with pytest.raises(WrtError, match=r"geometry_threshold = '0.9'"):
        load_features(str(features))


@pytest.mark.parametrize(
    "key, value",
    [("spp", "0"), ("spp", "-4"), ("spp", "2.5"), ("width", "7.9"), ("height", "6"), ("reference_spp", "true")],
)
def test_feature_counts_and_sizes_must_be_integers_in_range(tmp_path, key, value):
    """spp below 1 was accepted and 7.9 pixels became 7: counts and sizes are integers, spp >= 1,
    sizes >= the 7-pixel SSIM window."""
    entry = {"spp": "4", "width": "16", "height": "16", "reference_spp": "64"} | {key: value}
    features = tmp_path / "features.toml"
    features.write_text(
        '[[feature]]\nname = "x"\nscene = "wrt.examples:raycast/raycast_sphere.toml"\nintegrator = "raycast"\n'
        + "".join(f"{k} = {v}\n" for k, v in entry.items())
    )
    with pytest.raises(WrtError) as e:
        load_features(str(features))
    assert f"feature[0].{key} = " in str(e.value) and "must be an integer" in str(e.value), str(e.value)


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1.5", "-2"])
def test_compare_refuses_a_threshold_out_of_range(tmp_path, capsys, value):
    """Class 2: ``--threshold nan`` never failed."""
    a = np.random.default_rng(0).uniform(0, 1, (16, 16, 3)).astype(np.float32)
    write_image(str(tmp_path / "a.exr"), a)
    write_image(str(tmp_path / "b.exr"), a[::-1].copy())
    assert main(["compare", str(tmp_path / "a.exr"), str(tmp_path / "b.exr"), f"--threshold={value}"]) == 2
    err = one_error_line(capsys)
    assert "--threshold" in err and repr(float(value)) in err and "[-1, 1]" in err, err


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_compare_refuses_non_finite_pixels(tmp_path, capsys, bad):
    """Class 3: a NaN pixel counted as black in SSIM, so an image with holes scored as clean."""
    a = np.random.default_rng(1).uniform(0, 1, (16, 16, 3)).astype(np.float32)
    holed = a.copy()
    holed[4, 7] = bad
    write_image(str(tmp_path / "a.exr"), a)
    write_image(str(tmp_path / "holed.exr"), holed)
    for args in (["holed.exr", "a.exr"], ["a.exr", "holed.exr"], ["holed.exr", "holed.exr"]):
        assert main(["compare", *(str(tmp_path / p) for p in args), "--threshold", "0.5"]) == 2, args
        err = one_error_line(capsys)
        assert str(tmp_path / "holed.exr") in err and ("NaN" in err or "Inf" in err), err


def test_a_render_with_non_finite_pixels_fails_the_matrix(tmp_path, monkeypatch, capsys):
    """Class 3: the matrix scored a render with NaN pixels as if they were black."""
    copy_references(tmp_path, monkeypatch, [FEATURE])
    real = run.render_feature

    def holed(*args, **kwargs):
        result = real(*args, **kwargs)
        result.rgb = result.rgb.copy()
        result.rgb[10:12, 20:22] = np.nan
        return result

    monkeypatch.setattr(run, "render_feature", holed)
    result = run.evaluate(select(load_features(), [FEATURE])[0])
    assert not result.passed and any("non-finite" in f for f in result.failures), result.failures
    assert main(["matrix", FEATURE]) == 1
    assert "non-finite" in capsys.readouterr().out


MALFORMED = {
    "list": ("[1, 2, 3]", "not a JSON object (it holds an array)"),
    "empty_object": ("{}", "reference_sha256"),
    "string_threshold": (None, "ssim_threshold = '0.99'"),
    "missing_threshold": (None, "ssim_threshold"),
    "numeric_sha": (None, "reference_sha256 = 5"),
    "truncated": (None, "not a calibration file: not JSON"),
}


@pytest.mark.parametrize("shape", MALFORMED, ids=list(MALFORMED))
def test_a_malformed_calibration_is_one_line(tmp_path, monkeypatch, capsys, shape):
    """Class 4: a calibration of the wrong shape gave a traceback (or a 'crashed' feature)."""
    folder = copy_references(tmp_path, monkeypatch, [FEATURE])
    path = folder / f"{FEATURE}.json"
    text = path.read_text()
    data = json.loads(text)
    content, expected = MALFORMED[shape]
    if shape == "string_threshold":
        data["ssim_threshold"] = "0.99"
    elif shape == "missing_threshold":
        del data["ssim_threshold"]
    elif shape == "numeric_sha":
        data["reference_sha256"] = 5
    elif shape == "truncated":
        content = text[: len(text) // 2]
    path.write_text(json.dumps(data) if content is None else content)
    assert main(["matrix", FEATURE]) == 2
    err = one_error_line(capsys)
    assert str(path) in err and expected in err, err


@pytest.mark.parametrize("size", [(5, 5), (1, 1), (6, 40), (40, 6)])
def test_compare_refuses_images_smaller_than_the_ssim_window(tmp_path, capsys, size):
    """Class 5: images under 7x7 gave a ValueError traceback."""
    h, w = size
    write_image(str(tmp_path / "small.exr"), np.full((h, w, 3), 0.5, np.float32))
    assert main(["compare", str(tmp_path / "small.exr"), str(tmp_path / "small.exr")]) == 2
    err = one_error_line(capsys)
    assert str(tmp_path / "small.exr") in err and f"{w}x{h}" in err and "7x7" in err, err


def test_compare_refuses_images_of_different_sizes(tmp_path, capsys):
    write_image(str(tmp_path / "a.exr"), np.full((8, 9, 3), 0.5, np.float32))
    write_image(str(tmp_path / "b.exr"), np.full((9, 8, 3), 0.5, np.float32))
    assert main(["compare", str(tmp_path / "a.exr"), str(tmp_path / "b.exr")]) == 2
    err = one_error_line(capsys)
    assert str(tmp_path / "a.exr") in err and "9x8" in err and "8x9" in err, err


@pytest.mark.parametrize("spp", [0, -4])
def test_a_sample_count_below_one_is_refused(tmp_path, monkeypatch, capsys, spp):
    """Corrupt numbers in the metadata: the Z-test divides by wrt:spp (0 crashed, < 0 passed)."""
    folder = copy_references(tmp_path, monkeypatch, [FEATURE])
    exr = folder / f"{FEATURE}.exr"
    image = read_image(str(exr))
    write_image(str(exr), image.rgb, aovs=image.aovs, metadata={**image.metadata, "spp": spp}, half=True)
    data = json.loads((folder / f"{FEATURE}.json").read_text())
    data["reference_sha256"] = references.file_sha256(str(exr))
    (folder / f"{FEATURE}.json").write_text(json.dumps(data))
    assert main(["matrix", FEATURE]) == 2
    err = one_error_line(capsys)
    assert str(exr) in err and f"wrt:spp = {spp}" in err, err
    clean = tmp_path / "clean.exr"
    write_image(str(clean), image.rgb, aovs=image.aovs, metadata=image.metadata)
    assert main(["compare", str(exr), str(clean)]) == 2
    err = one_error_line(capsys)
    assert str(exr) in err and f"wrt:spp = {spp}" in err, err
