"""The path integrator against Mitsuba 3 (an independent renderer) on the same scenes, imported
from Mitsuba XML (wrt/mitsuba_xml.py). Skipped, with the reason, where Mitsuba cannot be loaded."""
from pathlib import Path

import numpy as np
import pytest

import wrt
from harness.score import ssim
from mitsuba_peer import mitsuba_available, render_mitsuba

EXAMPLES = Path(__file__).resolve().parent.parent / "examples" / "mitsuba"
AVAILABLE, REASON = mitsuba_available()
SPP = 128


def binned(image, k=4):
    """Mean over k x k pixel blocks: each block of a 128-spp render averages 2048 samples."""
    h, w = image.shape[0] // k * k, image.shape[1] // k * k
    return image[:h, :w].reshape(h // k, k, w // k, k, 3).mean(axis=(1, 3)).astype(np.float32)


@pytest.mark.skipif(not AVAILABLE, reason=REASON)
@pytest.mark.parametrize("name", ["glossy_sphere", "cornell_box"])
def test_path_integrator_agrees_with_mitsuba(name):
    """Equal spp, box filter, same camera: every channel's image mean within 2% (measured: under
    0.2%), and SSIM of the 4 x 4-binned tone-mapped images above 0.98 (measured 0.988-0.998; the
    unbinned images at 128 spp are still dominated by both renderers' noise)."""
    path = EXAMPLES / f"{name}.xml"
    ours = wrt.render(wrt.load_scene(path), spp=SPP).rgb.astype(np.float64)
    theirs = render_mitsuba(str(path), spp=SPP).astype(np.float64)
    assert ours.shape == theirs.shape and np.isfinite(ours).all()
    mean_ours, mean_theirs = ours.mean(axis=(0, 1)), theirs.mean(axis=(0, 1))
    np.testing.assert_allclose(mean_ours, mean_theirs, rtol=0.02)
    assert ssim(binned(ours), binned(theirs)) > 0.98
