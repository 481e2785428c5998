"""Tests for wrt.imageio: EXR/PNG round trips, the sRGB curve, atomic writes and errors."""

import os

import numpy as np
import OpenImageIO as oiio
import pytest

from wrt import imageio
from wrt.errors import WrtError
from wrt.imageio import (
    AOV_CHANNELS,
    read_image,
    srgb_decode,
    srgb_encode,
    tonemap_srgb,
    write_image,
)

H, W = 5, 7


def _rgb(seed=0):
    return np.random.default_rng(seed).uniform(0.0, 4.0, (H, W, 3)).astype(np.float32)


def _aovs():
    rng = np.random.default_rng(1)
    depth = rng.uniform(0.1, 100.0, (H, W)).astype(np.float32)
    depth[0, 0] = np.inf
    normal = rng.normal(size=(H, W, 3)).astype(np.float32)
    normal /= np.linalg.norm(normal, axis=2, keepdims=True)
    ids = rng.integers(-1, 9, (H, W)).astype(np.int32)
    ids[0, 0] = -1
    position = rng.uniform(-1e3, 1e3, (H, W, 3)).astype(np.float32)
    variance = rng.uniform(0.0, 2.0, (H, W, 3)).astype(np.float32)
    spp = rng.integers(16, 1025, (H, W)).astype(np.float32)
    return {"depth": depth, "normal": normal, "object_id": ids, "position": position, "variance": variance, "spp": spp}


def _sorted_listing(folder):
    return sorted(os.listdir(folder))


def _srgb_closed_form(x):
    x = min(max(x, 0.0), 1.0)
    return 12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055


def test_exr_round_trip_rgb_aovs_metadata_exact(tmp_path):
    path = tmp_path / "out.exr"
    rgb, aovs = _rgb(), _aovs()
    metadata = {
        "version": "0.1.0",
        "scene": "cornell.toml",
        "spp": 64,
        "seed": 7,
        "integrator": "path",
        "render_time_s": 1.5,
    }
    write_image(path, rgb, aovs=aovs, metadata=metadata)
    image = read_image(path)
    np.testing.assert_array_equal(image.rgb, rgb)
    assert image.rgb.dtype == np.float32
    assert set(image.aovs) == set(AOV_CHANNELS)
    for name, values in aovs.items():
        np.testing.assert_array_equal(image.aovs[name], values)
    assert image.aovs["object_id"].dtype == np.int32
    assert image.aovs["depth"][0, 0] == np.inf
    assert image.aovs["object_id"][0, 0] == -1
    assert image.metadata == metadata
    assert {type(v) for v in image.metadata.values()} == {str, int, float}


def test_exr_channel_names_are_the_public_contract(tmp_path):
    path = tmp_path / "out.exr"
    write_image(path, _rgb(), aovs=_aovs())
    inp = oiio.ImageInput.open(str(path))
    names = set(inp.spec().channelnames)
    inp.close()
    expected = {"R", "G", "B", "Z", "N.X", "N.Y", "N.Z", "id", "P.X", "P.Y", "P.Z", "var.R", "var.G", "var.B", "spp"}
    assert names == expected


def test_exr_half_rgb_within_half_precision_and_aovs_stay_float32(tmp_path):
    path = tmp_path / "half.exr"
    rgb, aovs = _rgb(), _aovs()
    write_image(path, rgb, aovs=aovs, half=True)
    inp = oiio.ImageInput.open(str(path))
    spec = inp.spec()
    inp.close()
    formats = dict(zip(spec.channelnames, (str(f) for f in spec.channelformats)))
    assert {formats[c] for c in "RGB"} == {"half"}
    assert {formats[c] for c in ("Z", "id", "N.X", "P.Z")} == {"float"}
    image = read_image(path)
    np.testing.assert_array_equal(image.rgb, rgb.astype(np.float16).astype(np.float32))
    np.testing.assert_allclose(image.rgb, rgb, rtol=2.0**-11)
    np.testing.assert_array_equal(image.aovs["position"], aovs["position"])


def test_exr_nonfinite_rgb_survives(tmp_path):
    path = tmp_path / "nan.exr"
    rgb = _rgb()
    rgb[1, 2] = [np.nan, np.inf, -np.inf]
    write_image(path, rgb)
    np.testing.assert_array_equal(read_image(path).rgb, rgb)


@pytest.mark.parametrize("x", [0.0, 0.0031308, 0.01, 0.5, 1.0])
def test_srgb_encode_matches_closed_form(x):
    assert srgb_encode(np.array([x]))[0] == pytest.approx(_srgb_closed_form(x), abs=1e-15)


def test_tonemap_srgb_values():
    x = np.array([0.0, 0.0031308, 0.5, 1.0, 2.0, -0.5, np.nan, np.inf, 0.18], dtype=np.float32)
    rgb = np.repeat(x[None, :, None], 3, axis=2)
    out = tonemap_srgb(rgb)
    assert out.dtype == np.uint8 and out.shape == rgb.shape
    expected = [0, 10, 188, 255, 255, 0, 0, 255, 118]
    assert out[0, :, 0].tolist() == expected
    assert expected[:5] == [round(255 * _srgb_closed_form(float(v))) for v in x[:5]]


def test_srgb_decode_inverts_encode():
    x = np.linspace(0.0, 1.0, 1001)
    np.testing.assert_allclose(srgb_decode(srgb_encode(x)), x, atol=1e-12)


def test_png_is_tonemapped_and_reads_back_linear(tmp_path):
    path = tmp_path / "out.PNG"
    rgb = _rgb()
    write_image(path, rgb, metadata={"spp": 4})
    inp = oiio.ImageInput.open(str(path))
    assert inp.format_name() == "png"
    pixels = inp.read_image("uint8")
    inp.close()
    np.testing.assert_array_equal(pixels, tonemap_srgb(rgb))
    image = read_image(path)
    np.testing.assert_allclose(image.rgb, srgb_decode(tonemap_srgb(rgb) / 255.0), rtol=1e-6)
    assert image.rgb.dtype == np.float32
    assert image.aovs == {}
    assert image.metadata == {"spp": "4"}


def test_png_with_aovs_is_rejected(tmp_path):
    with pytest.raises(WrtError, match=r"AOVs need an \.exr output"):
        write_image(tmp_path / "out.png", _rgb(), aovs={"depth": np.ones((H, W), np.float32)})
    assert _sorted_listing(tmp_path) == []


def test_failed_write_keeps_previous_file_and_leaves_no_temp(tmp_path, monkeypatch):
    path = tmp_path / "out.exr"
    old = _rgb(seed=1)
    write_image(path, old)
    before = path.read_bytes()

    def interrupted(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(imageio.os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_image(path, _rgb(seed=2))
    assert path.read_bytes() == before
    assert _sorted_listing(tmp_path) == ["out.exr"]
    np.testing.assert_array_equal(read_image(path).rgb, old)


def test_oiio_write_failure_becomes_wrterror_and_leaves_no_temp(tmp_path, monkeypatch):
    path = tmp_path / "out.exr"
    write_image(path, _rgb(seed=1))
    before = path.read_bytes()

    class FailingOutput:
        def open(self, name, spec):
            return True

        def write_image(self, pixels):
            return False

        def geterror(self):
            return "disk full"

        def close(self):
            return True

    monkeypatch.setattr(imageio.oiio.ImageOutput, "create", lambda name: FailingOutput())
    with pytest.raises(WrtError, match="disk full") as info:
        write_image(path, _rgb(seed=2))
    assert str(path) in str(info.value)
    assert path.read_bytes() == before
    assert _sorted_listing(tmp_path) == ["out.exr"]


def test_new_file_gets_umask_permissions(tmp_path):
    path = tmp_path / "out.exr"
    write_image(path, _rgb())
    mask = os.umask(0)
    os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask


@pytest.mark.parametrize("name", ["out.jpg", "out.tiff", "out"])
def test_unsupported_extension(tmp_path, name):
    with pytest.raises(WrtError, match=r"\.exr, \.png"):
        write_image(tmp_path / name, _rgb())
    with pytest.raises(WrtError, match=name):
        read_image(tmp_path / name)


def test_missing_folder(tmp_path):
    folder = tmp_path / "nope"
    with pytest.raises(WrtError, match="nope"):
        write_image(folder / "out.exr", _rgb())
    assert not folder.exists()


def test_missing_file(tmp_path):
    with pytest.raises(WrtError, match="no such file"):
        read_image(tmp_path / "absent.exr")


def test_corrupt_file(tmp_path):
    path = tmp_path / "x.exr"
    path.write_bytes(np.random.default_rng(0).bytes(512))
    with pytest.raises(WrtError, match="x.exr"):
        read_image(path)


def test_truncated_file(tmp_path):
    path = tmp_path / "big.exr"
    write_image(path, np.random.default_rng(0).random((64, 64, 3)).astype(np.float32))
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(WrtError, match="big.exr"):
        read_image(path)


@pytest.mark.parametrize(
    "rgb",
    [np.zeros((H, W), np.float32), np.zeros((H, W, 4), np.float32), np.zeros((0, W, 3)), np.zeros((H, W, 3), np.uint8)],
)
def test_bad_rgb(tmp_path, rgb):
    with pytest.raises(ValueError, match="rgb"):
        write_image(tmp_path / "out.exr", rgb)


@pytest.mark.parametrize(
    "aovs, match",
    [
        ({"albedo": np.zeros((H, W, 3), np.float32)}, "unknown AOV 'albedo'"),
        ({"depth": np.zeros((H, W + 1), np.float32)}, "'depth' must have shape"),
        ({"normal": np.zeros((H, W), np.float32)}, "'normal' must have shape"),
        ({"object_id": np.zeros((H, W), np.float32)}, "'object_id' must be an integer"),
        ({"object_id": np.full((H, W), 2**24 + 1)}, "exact in float32"),
        ({"position": np.zeros((H, W, 3), np.int32)}, "'position' must be a floating"),
    ],
)
def test_bad_aovs(tmp_path, aovs, match):
    with pytest.raises(ValueError, match=match):
        write_image(tmp_path / "out.exr", _rgb(), aovs=aovs)


@pytest.mark.parametrize("metadata", [{"spp": 2**31}, {"flag": True}, {"list": [1]}, {1: "x"}])
def test_bad_metadata(tmp_path, metadata):
    with pytest.raises(ValueError, match="metadata"):
        write_image(tmp_path / "out.exr", _rgb(), metadata=metadata)


def test_temporary_files_of_killed_writers_are_cleaned_by_the_next_write(tmp_path):
    """A writer killed mid-write (kill -9) leaves ``.NAME.PID.XXXXXXXX.exr``; the next write to the
    same image removes it when that process is gone, and leaves a live one's and other images'
    alone (issue 13: nothing ever cleaned them)."""
    out = tmp_path / "img.exr"
    dead = tmp_path / ".img.exr.999999999.abcdefgh.exr"  # above any pid_max: no such process
    live = tmp_path / ".img.exr.1.abcdefgh.exr"  # pid 1 is always running
    other = tmp_path / ".other.exr.999999999.abcdefgh.exr"
    for f in (dead, live, other):
        f.write_bytes(b"partial")
    write_image(out, np.zeros((4, 4, 3), np.float32))
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted([out.name, live.name, other.name])
