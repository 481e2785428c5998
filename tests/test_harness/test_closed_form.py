"""The closed-form check (harness/closed_form.py): features whose exact image mean is known (the
furnaces deep_path and depth_count), their references against it, their wrong variants, and the
features file's ``closed_form_mean`` key."""

import numpy as np
import pytest
from conftest import one_feature_file
from wrt_harness.closed_form import CLOSED_FORM_K, HALF_RTOL, closed_form_failure
from wrt_harness.matrix import load_features
from wrt_harness.references import load_reference, render_feature

from wrt.errors import WrtError

CLOSED_FORM_FEATURES = [f for f in load_features() if f.closed_form_mean is not None]
IDS = [f.name for f in CLOSED_FORM_FEATURES]


def test_the_furnaces_have_closed_forms():
    assert {"deep_path", "depth_count"} <= set(IDS)


@pytest.mark.parametrize("feature", CLOSED_FORM_FEATURES, ids=IDS)
def test_the_reference_matches_its_closed_form(feature):
    """The reference (ref_spp samples per pixel) is the closed form within its noise and the
    rounding of its half floats."""
    reference = load_reference(feature)
    miss = closed_form_failure(
        feature.closed_form_mean, [(reference.rgb, reference.spp)], reference.variance, rtol=HALF_RTOL
    )
    assert miss is None, miss


@pytest.mark.parametrize("feature", CLOSED_FORM_FEATURES, ids=IDS)
def test_the_wrong_variant_misses_its_closed_form(feature):
    """One render of the wrong variant (a changed max_depth) at the test spp is rejected."""
    reference = load_reference(feature)
    render = render_feature(feature, wrong=True)
    miss = closed_form_failure(feature.closed_form_mean, [(render.rgb, render.spp)], reference.variance)
    assert miss is not None and "closed form: image mean" in miss


def test_renders_are_pooled_by_spp_and_judged_by_their_standard_error():
    variance = np.full((10, 10, 3), 4.0)  # per-sample standard deviation 2
    expected = [1.0, 1.0, 1.0]
    # 100 pixels x (4 + 16) samples: standard error 2 / sqrt(2000) = 0.0447
    se = 2.0 / np.sqrt(2000.0)
    low = np.full((10, 10, 3), 1.0 - 5 * CLOSED_FORM_K * se, np.float32)
    high = np.full((10, 10, 3), 1.0 + 1.25 * CLOSED_FORM_K * se, np.float32)
    # pooled by spp (4 low, 16 high): off by exactly 0 standard errors
    assert closed_form_failure(expected, [(low, 4), (high, 16)], variance) is None
    # pooled equally, it would be off by 1.9 CLOSED_FORM_K standard errors
    assert closed_form_failure(expected, [(low, 10), (high, 10)], variance) is not None
    inside = np.full((10, 10, 3), 1.0 + 0.9 * CLOSED_FORM_K * se, np.float32)
    outside = inside.copy()
    outside[..., 1] = 1.0 + 1.1 * CLOSED_FORM_K * se
    assert closed_form_failure(expected, [(inside, 20)], variance) is None
    miss = closed_form_failure(expected, [(outside, 20)], variance)
    assert miss is not None and "G 1.1" in miss and "R " not in miss and "B " not in miss, miss


def test_a_deterministic_render_is_held_to_float32_rounding():
    variance = np.zeros((8, 8, 3))
    expected = [0.5, 0.25, 0.125]
    exact = np.broadcast_to(np.float32(expected), (8, 8, 3))
    assert closed_form_failure(expected, [(exact, 1)], variance) is None
    off = exact * np.float32([1.0, 1.0, 1.001])
    assert closed_form_failure(expected, [(off, 1)], variance) is not None


def test_a_nan_misses():
    image = np.full((8, 8, 3), 0.5, np.float32)
    image[3, 3, 0] = np.nan
    assert closed_form_failure([0.5, 0.5, 0.5], [(image, 4)], np.full((8, 8, 3), 0.01)) is not None


@pytest.mark.parametrize("value", ["[0.5, 0.5]", "[0.5, 0.5, nan]", "[0.5, -0.1, 0.5]", '"0.5"', "[0.5, true, 0.5]"])
def test_a_bad_closed_form_mean_is_refused(tmp_path, value):
    features = one_feature_file(tmp_path, f"closed_form_mean = {value}")
    with pytest.raises(WrtError) as e:
        load_features(str(features))
    message = str(e.value)
    assert f"{features}: feature[0].closed_form_mean = " in message and "three finite numbers" in message, message
