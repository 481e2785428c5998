"""The closed-form check: the image mean of a feature whose exact answer is known.

A feature with ``closed_form_mean = [r, g, b]`` in its features file (a furnace: every pixel's
radiance is known in closed form, ``examples/path/deep_furnace.toml``) has the mean of its
renders over the image tested against that value, per channel. The renders are independent
(their own seeds) and pooled by their spp; their noise is judged with the reference's per-sample
variance (``Reference.variance``, per pixel and channel): pixels are independent under the
matrix's independent sampler, so the pooled image mean of ``n`` samples per pixel over ``P``
pixels has the variance ``mean(variance) / (n P)``. A channel fails when it is more than
``CLOSED_FORM_K`` standard errors off, or, where the variance is 0 (a deterministic render), more
than the float32 tolerance ``rtol`` (relative).
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtri

CLOSED_FORM_ALPHA = 1e-3  # false-alarm rate of the check, all three channels together
# two-sided, Bonferroni over 3 channels: 3.59 standard errors
CLOSED_FORM_K = float(ndtri(1.0 - CLOSED_FORM_ALPHA / 6.0))
FLOAT32_RTOL = 1e-4  # float32 rounding of a pixel's sums over samples and segments, relative
HALF_RTOL = 2.0**-11  # the spacing of half floats (a reference EXR's RGB), relative: its rounding's bound


def closed_form_failure(
    expected, renders: list[tuple[np.ndarray, int]], variance: np.ndarray, rtol: float = FLOAT32_RTOL
) -> str | None:
    """Why the image mean of ``renders`` ((H, W, 3) linear RGB, its spp; independent samples)
    misses the closed form ``expected`` (linear RGB), judged with the per-sample ``variance``
    (H, W, 3), or None where it does not. A NaN fails."""
    expected = np.asarray(expected, dtype=np.float64)
    samples = sum(spp for _, spp in renders)
    mean = sum(rgb.astype(np.float64).mean(axis=(0, 1)) * spp for rgb, spp in renders) / samples
    pixels = variance.shape[0] * variance.shape[1]
    se = np.sqrt(variance.astype(np.float64).mean(axis=(0, 1)) / (samples * pixels))
    tolerance = np.maximum(CLOSED_FORM_K * se, rtol * np.abs(expected))
    off = ~(np.abs(mean - expected) <= tolerance)
    if not off.any():
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        z = (mean - expected) / se  # +-inf for a deterministic render
        relative = mean / expected - 1.0
    misses = ", ".join(
        f"{'RGB'[c]} {mean[c]:.5f} vs {expected[c]:.5f} ({relative[c]:+.2%}, z {z[c]:+.1f})"
        for c in np.flatnonzero(off)
    )
    return (
        f"closed form: image mean {misses} over {samples} spp "
        f"(passes within {CLOSED_FORM_K:.2f} standard errors, or {rtol:.0e} relative)"
    )
