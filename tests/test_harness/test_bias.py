"""The bias test of region means (harness/score.py ``bias_test``) and the false-alarm count
(harness/false_alarms.py): its false-alarm rate on unbiased noise is its level, it catches a 1%
global bias at the matrix's spp, it refuses NaN, and a biased renderer fails a real feature by it."""

import dataclasses

import numpy as np
import pytest
import wrt_harness.run as run
from wrt_harness.false_alarms import false_alarms, seeds
from wrt_harness.matrix import load_features, select
from wrt_harness.score import BIAS_ALPHA, bias_test

SHAPE = (72, 96, 3)


def noisy(rng, mean, variance, spp):
    """A render of ``spp`` Gaussian samples per pixel: exactly what the test's model assumes."""
    return mean + rng.normal(size=mean.shape) * np.sqrt(variance / spp)


def test_false_alarm_rate_is_the_level_and_a_1_percent_bias_is_caught():
    rng = np.random.default_rng(1)
    mean = rng.uniform(0.05, 1.0, SHAPE)
    variance = (rng.uniform(0.5, 3.0, SHAPE) * mean) ** 2  # per-sample relative std 0.5-3, as in path traced images
    spp, ref_spp = 21 * 16, 1024
    trials = 4000
    alarms = sum(
        not bias_test(
            noisy(rng, mean, variance, spp), spp, noisy(rng, mean, variance, ref_spp), variance, ref_spp
        ).passed
        for _ in range(trials)
    )
    assert alarms <= 3 * BIAS_ALPHA * trials + 3  # Bonferroni: at most the level (about 1e-3), here 0-4 of 4000
    caught = sum(
        not bias_test(1.01 * noisy(rng, mean, variance, spp), spp, mean, variance, ref_spp).passed for _ in range(50)
    )
    assert caught == 50
    local = noisy(rng, mean, variance, spp)
    local[:18, :24] *= 1.05  # one cell of the 4 x 4 grid 5% too bright
    result = bias_test(local, spp, mean, variance, ref_spp)
    assert not result.passed and result.worst.startswith("region (row 0, col 0)")


def test_nan_fails():
    mean = np.ones(SHAPE)
    image = mean.copy()
    image[3, 4, 1] = np.nan
    result = bias_test(image, 16, mean, np.ones(SHAPE), 1024)
    assert not result.passed and np.isnan(result.max_z)
    assert not bias_test(mean, 16, mean, np.full(SHAPE, np.nan), 1024).passed


def test_a_one_percent_darker_renderer_fails_by_bias(monkeypatch):
    """soft_shadows renders 1% too dark: per-pixel noise hides it from SSIM and the Z-test, the
    pooled region means do not."""
    feature = select(load_features(), ["soft_shadows"])[0]
    render = run.render_feature

    def darker(*args, **kwargs):
        result = render(*args, **kwargs)
        return dataclasses.replace(result, rgb=0.99 * result.rgb)

    monkeypatch.setattr(run, "render_feature", darker)
    result = run.evaluate(feature)
    assert "bias" in result.failed_checks, result.failures
    assert result.bias.image_bias[1] == pytest.approx(-0.01, abs=0.003)


def test_false_alarms_counts_failing_seeds(monkeypatch):
    feature = select(load_features(), ["antialiasing"])[0]
    assert len(set(seeds(50))) == 50
    clean = false_alarms(feature, 2)
    assert clean["seeds"] == 2 and clean["failing_seeds"] == 0, clean["failures"]
    render = run.render_feature

    def brighter(*args, **kwargs):
        result = render(*args, **kwargs)
        return dataclasses.replace(result, rgb=1.02 * result.rgb)

    monkeypatch.setattr(run, "render_feature", brighter)
    broken = false_alarms(feature, 2)
    assert broken["failing_seeds"] == 2 and broken["by_check"]["bias"] == 2 and broken["rate"] == 1.0


def test_per_pixel_sample_counts_weigh_each_pixel_by_its_own():
    """An adaptive render's pixels hold different sample counts (its ``spp`` AOV): the Z-test, the
    bias test, pooling and the batch variance take them pixel by pixel. Uniform counts give the
    scalar results exactly; a render whose busy half took 16x the samples is scored by them: at
    the scalar (smallest) count its noise is overestimated and a 1% bias hides, at its own it shows."""
    from wrt_harness.score import batch_variance, pooled, z_test

    rng = np.random.default_rng(7)
    mean = rng.uniform(0.05, 1.0, SHAPE)
    variance = (rng.uniform(0.5, 3.0, SHAPE) * mean) ** 2
    counts = np.full(SHAPE[:2], 64)
    image = noisy(rng, mean, variance, 64)
    reference = noisy(rng, mean, variance, 4096)
    assert z_test(image, counts, reference, variance, 4096) == z_test(image, 64, reference, variance, 4096)
    assert bias_test(image, counts, reference, variance, 4096) == bias_test(image, 64, reference, variance, 4096)
    a, b = noisy(rng, mean, variance, 16), noisy(rng, mean, variance, 48)
    assert np.array_equal(pooled([a, b], [np.full(SHAPE[:2], 16), np.full(SHAPE[:2], 48)]), pooled([a, b], [16, 48]))
    assert np.allclose(batch_variance([a, b], [np.full(SHAPE[:2], 16), 48]), batch_variance([a, b], [16, 48]))

    counts = np.where(np.arange(SHAPE[1]) < SHAPE[1] // 2, 64, 1024)[None, :].repeat(SHAPE[0], axis=0)
    biased = 0.99 * (mean + rng.normal(size=SHAPE) * np.sqrt(variance / counts[..., None]))
    assert bias_test(biased, 64, reference, variance, 4096).passed
    assert not bias_test(biased, counts, reference, variance, 4096).passed
