"""Features rendered in several progressive passes (``passes``) or adaptively (``target_error``):
the matrix entry's keys, and how such a render is made and scored (harness/references.py
``render_feature``, harness/run.py)."""

import numpy as np
import pytest
from conftest import one_feature_file
from wrt_harness.matrix import load_features

from wrt.errors import WrtError


@pytest.mark.parametrize(
    "extra, message",
    [
        ("passes = 0", "passes = 0: must be an integer >= 1"),
        ("passes = 2.0", "passes = 2.0: must be an integer >= 1"),
        ("spp = 9\npasses = 2", "passes = 2: must divide spp = 9"),
        ("spp = 64\ntarget_error = 0", "target_error = 0: must be a number in (0, 1)"),
        ("spp = 64\ntarget_error = nan", "target_error = nan: must be a number in (0, 1)"),
        ("spp = 64\ntarget_error = true", "target_error = True: must be a number in (0, 1)"),
        ("spp = 16\ntarget_error = 0.1", "needs spp >= 32"),
    ],
)
def test_bad_passes_or_target_error_are_refused(tmp_path, extra, message):
    features = one_feature_file(tmp_path, extra)
    with pytest.raises(WrtError) as e:
        load_features(str(features))
    assert f"{features}: feature[0]" in str(e.value) and message in str(e.value), str(e.value)


def test_a_progressive_feature_is_rendered_in_its_passes_and_a_reference_in_one(tmp_path, monkeypatch):
    import wrt_harness.references as references

    import wrt

    feature = load_features(str(one_feature_file(tmp_path, "spp = 6\npasses = 3")))[0]
    calls = []
    real = wrt.render

    def recorded(scene, **kwargs):
        calls.append(kwargs)
        return real(scene, **kwargs)

    monkeypatch.setattr(references.wrt, "render", recorded)
    tested = references.render_feature(feature)
    plain = references.render_feature(feature, as_tested=False)
    assert calls[0]["progress_every"] == 2 and calls[0]["progress"](1, 6, 0.0, None) is True
    assert "progress" not in calls[1]
    assert np.array_equal(tested.rgb, plain.rgb)  # passes change nothing
    assert references.samples(tested) == 6


def test_an_adaptive_feature_aims_at_a_smaller_error_with_more_samples(tmp_path, monkeypatch):
    import wrt_harness.references as references

    feature = load_features(str(one_feature_file(tmp_path, "spp = 32\ntarget_error = 0.2")))[0]
    calls = []
    monkeypatch.setattr(references.wrt, "render", lambda scene, **kwargs: calls.append(kwargs))
    references.render_feature(feature)
    references.render_feature(feature, spp=128)
    references.render_feature(feature, spp=512, as_tested=False)
    assert calls[0]["target_error"] == pytest.approx(0.2) and calls[1]["target_error"] == pytest.approx(0.1)
    assert "target_error" not in calls[2]  # references are plain renders


def test_an_adaptive_render_is_held_to_its_sample_counts(monkeypatch):
    """Each pixel of an adaptive render is bit for bit the pixel of a plain render of the samples
    its spp AOV says it took: counts that lie (here: a pixel that took 32 said to have taken 16)
    fail the adaptive check, with the image itself unchanged."""
    import wrt_harness.run as run
    from wrt_harness.matrix import select

    feature = select(load_features(), ["adaptive_sampling"])[0]
    assert run.evaluate(feature).passed
    real = run.render_feature

    def lying(*args, **kwargs):
        result = real(*args, **kwargs)
        if "spp" in result.aovs:
            result.aovs["spp"] = np.where(result.aovs["spp"] == 32, 16, result.aovs["spp"])
        return result

    monkeypatch.setattr(run, "render_feature", lying)
    result = run.evaluate(feature)
    assert "adaptive" in result.failed_checks, result.failures
    assert any("spp AOV says 16 samples" in f for f in result.failures), result.failures


def test_a_render_in_passes_that_differs_from_one_pass_fails(monkeypatch):
    import wrt_harness.run as run
    from wrt_harness.matrix import select

    feature = select(load_features(), ["progressive_passes"])[0]
    real = run.render_feature

    def drifting(*args, as_tested=True, **kwargs):
        result = real(*args, as_tested=as_tested, **kwargs)
        if as_tested:
            result.rgb = np.nextafter(result.rgb, np.float32(np.inf))  # one float32 ulp: invisible, not exact
        return result

    monkeypatch.setattr(run, "render_feature", drifting)
    result = run.evaluate(feature)
    assert result.failed_checks == ["progressive"], result.failures
