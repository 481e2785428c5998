"""Adaptive sampling (`wrt.render(..., target_error=...)`, `wrt render --target-error`): noisy
pixels get more samples, converged ones stop, the result stays deterministic and unbiased."""

import numpy as np
import pytest
from conftest import make_scene

import wrt
from wrt.cli import main
from wrt.imageio import read_image
from wrt.renderer import ADAPTIVE_FIRST_PASS, adaptive_passes, relative_error

AREA = {"type": "area", "corner": [-0.5, 2, -0.5], "edge_u": [1, 0, 0], "edge_v": [0, 0, 1], "radiance": [5, 5, 5]}
SHAPES = [
    {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "g"},
    {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": "g"},
]
CAM = {"origin": [0, 1.5, 3], "look_at": [0, 0.4, 0], "fov": 60}  # the top rows see the black sky


def scene(**render):
    return make_scene(
        SHAPES,
        materials=[{"name": "g", "albedo": [0.6, 0.6, 0.6]}],
        lights=[AREA],
        camera=CAM,
        render={"width": 32, "height": 24, "integrator": "path", **render},
    )


def test_pass_schedule_doubles_from_the_first_pass():
    assert adaptive_passes(256) == [16, 32, 64, 128, 256]
    assert adaptive_passes(100) == [16, 32, 64, 100]
    assert adaptive_passes(8) == [8]


def test_relative_error_of_known_samples():
    samples = np.array([1.0, 3.0, 1.0, 3.0])  # luminance of grey RGB samples: mean 2, squared deviations 4
    err = relative_error(np.full((1, 3), samples.sum()), np.array([(samples**2).sum()]), 4)
    assert err[0] == pytest.approx(np.sqrt((4 + 2**2) / 3 / 4) / 2)  # one pseudo-sample 2 away from the mean
    black = relative_error(np.zeros((1, 3)), np.zeros(1), 16)  # agreeing samples are not proof of convergence
    assert black[0] == pytest.approx(1 / np.sqrt(16 * 15))


def test_noisy_pixels_get_more_samples_and_black_sky_stops_first(device):
    r = wrt.render(scene(), spp=256, target_error=0.05, device=device)
    counts = r.aovs["spp"]
    assert counts.dtype == np.int32 and counts.shape == (24, 32)
    sky = r.rgb.sum(axis=2) == 0
    assert sky.any() and np.all(counts[sky] == 32)  # zero samples: stops once 1/sqrt(n (n-1)) < 0.05
    assert counts.min() >= ADAPTIVE_FIRST_PASS and counts.max() == 256 and r.spp == 256
    assert set(np.unique(counts)) <= set(adaptive_passes(256))


def test_adaptive_images_are_deterministic_and_unbiased(device):
    s = scene()
    a = wrt.render(s, spp=128, target_error=0.05, threads=1, device=device)
    b = wrt.render(s, spp=128, target_error=0.05, threads=2, device=device)
    assert np.array_equal(a.rgb, b.rgb) and np.array_equal(a.aovs["spp"], b.aovs["spp"])
    reference = wrt.render(s, spp=2048, seed=7, device=device).rgb.astype(np.float64)
    lum = np.array([0.2126, 0.7152, 0.0722])
    ours, true = a.rgb.astype(np.float64) @ lum, reference @ lum
    assert ours.mean() == pytest.approx(true.mean(), rel=0.02)
    # pixels that stopped early did so because their estimated error fell under the target: their
    # actual errors are of that size (median |error| of a normal error of std s is 0.67 s)
    stopped = (a.aovs["spp"] < 128) & (true > 0.01)
    assert stopped.sum() > 100
    assert np.median(np.abs(ours - true)[stopped] / true[stopped]) < 0.05


def test_target_error_must_be_positive():
    with pytest.raises(wrt.WrtError, match="target_error"):
        wrt.render(scene(), spp=16, target_error=0.0)


def test_cli_writes_the_sample_count_aov(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(
        '[render]\nwidth = 16\nheight = 12\nintegrator = "path"\nspp = 64\n[camera]\norigin = [0, 1.5, 3]\nlook_at = '
        "[0, 0.4, 0]\n"
        '[[shape]]\ntype = "sphere"\ncenter = [0, 0.5, 0]\nradius = 0.5\n'
        '[[light]]\ntype = "area"\ncorner = [-0.5, 2, -0.5]\nedge_u = [1, 0, 0]\nedge_v = [0, 0, 1]\nradiance = [5, '
        "5, 5]\n"
    )
    out = tmp_path / "o.exr"
    assert main(["render", str(path), "-o", str(out), "--target-error", "0.05"]) == 0
    summary = capsys.readouterr().out
    assert "64 spp (adaptive: " in summary  # the rate counts the samples taken, not 64 per pixel
    image = read_image(out)
    counts = image.aovs["spp"]
    assert (
        counts.shape == (12, 16)
        and counts.min() >= ADAPTIVE_FIRST_PASS
        and set(np.unique(counts)) <= set(adaptive_passes(64))
    )
    assert image.metadata["target_error"] == pytest.approx(0.05)
    assert main(["render", str(path), "-o", str(out), "--target-error", "-1"]) == 2
    capsys.readouterr()
    # every pixel converged in the first pass: a finished render, not an interrupted one (issue 13)
    assert main(["render", str(path), "-o", str(out), "--target-error", "100"]) == 0
    assert "interrupted" not in capsys.readouterr().err and read_image(out).aovs["spp"].max() == ADAPTIVE_FIRST_PASS
