"""Image scores of the regression harness: SSIM, RMSE, max error, a per-pixel Z-test, convergence.

SSIM is computed on tone-mapped images (clip to [0, 1], sRGB curve: what a person sees) with
scikit-image's ``structural_similarity(channel_axis=-1, data_range=1.0)``; RMSE and the maximum
absolute error on the linear float images.

References
----------
Z. Wang, A. Bovik, H. Sheikh, E. Simoncelli, "Image Quality Assessment: From Error Visibility to
Structural Similarity", IEEE TIP 13(4), 2004.
W. Jakob et al., Mitsuba 3 render tests (``mitsuba/python/tests/test_renders.py``): per-pixel
Z-test of a render against a reference with a Bonferroni-corrected significance level.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter
from scipy.special import erfc
from skimage.metrics import structural_similarity

from wrt.imageio import srgb_encode

SSIM_DATA_RANGE = 1.0  # tone-mapped images live in [0, 1]
Z_TEST_ALPHA = 0.01  # family-wise significance level of the per-pixel test
# Standard deviation floor of the Z-test: float32 rounding and CPU/CUDA differences make even a
# noise-free render differ from its reference by this much (absolute + relative to the value).
Z_FLOOR_ABS = 1e-4
Z_FLOOR_REL = 1e-3
# A block's variance is the largest of its neighbourhood's: a sliver of a bright object that the
# reference's samples rarely or never hit sits next to pixels whose variance shows the edge.
VARIANCE_NEIGHBOURHOOD = 5


def ssim(image: np.ndarray, reference: np.ndarray) -> float:
    """SSIM of two linear RGB images (H, W, 3), at least 7 x 7, after tone mapping to sRGB in [0, 1]
    (7 x 7 Gaussian-free uniform windows, scikit-image's defaults)."""
    if image.shape != reference.shape:
        raise ValueError(f"image shape {image.shape} differs from reference shape {reference.shape}")
    if min(image.shape[:2]) < 7:
        raise ValueError(f"SSIM needs images of at least 7 x 7 pixels, got {image.shape[1]} x {image.shape[0]}")
    return float(
        structural_similarity(srgb_encode(image), srgb_encode(reference), channel_axis=-1, data_range=SSIM_DATA_RANGE)
    )


def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """Root mean square error of the linear values."""
    return float(np.sqrt(np.mean((np.asarray(image, np.float64) - reference) ** 2)))


def max_error(image: np.ndarray, reference: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(image, np.float64) - reference)))


@dataclass(frozen=True)
class ZTest:
    """Outcome of the per-pixel Z-test of a render's mean against a reference."""

    passed: bool
    min_p: float  # smallest two-sided p-value over all pixels and channels
    threshold: float  # Bonferroni-corrected level: alpha / number of tests
    rejected: int  # pixels x channels with p below the threshold


def bin2x2(image: np.ndarray) -> np.ndarray:
    """Mean over 2 x 2 pixel blocks (a trailing odd row or column is dropped)."""
    h, w = image.shape[0] // 2 * 2, image.shape[1] // 2 * 2
    a = np.asarray(image[:h, :w], np.float64)
    return 0.25 * (a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2])


def z_test(image: np.ndarray, spp: int, reference: np.ndarray, ref_variance: np.ndarray, ref_spp: int) -> ZTest:
    """Is ``image`` (a mean of ``spp`` samples per pixel) an unbiased estimate of ``reference``?

    The test runs on 2 x 2 pixel blocks: each block mean averages 4 spp samples, which tames the
    skewed per-pixel distributions of edges and small highlights at low spp (a bias does not
    average away). ``ref_variance`` is the per-sample variance of each pixel (stored with the
    reference); a block's variance is the largest over its ``VARIANCE_NEIGHBOURHOOD``-wide
    neighbourhood of blocks (rare events the reference under-sampled sit beside edges whose
    variance shows), and its standard error ``sqrt(var/4 (1/spp + 1/ref_spp))``, floored by
    ``Z_FLOOR_ABS + Z_FLOOR_REL |reference|``. Every block and channel is a two-sided test; the
    family is controlled by Bonferroni (level ``Z_TEST_ALPHA / n``), so noise alone fails the
    whole image with probability under 1%, while a shifted mean fails it.
    """
    image, reference = bin2x2(image), bin2x2(reference)
    diff = image - reference
    block_var = np.maximum(bin2x2(ref_variance), 0.0) / 4.0
    block_var = maximum_filter(block_var, size=(VARIANCE_NEIGHBOURHOOD, VARIANCE_NEIGHBOURHOOD, 1), mode="nearest")
    var = block_var * (1.0 / spp + 1.0 / ref_spp)
    sigma = np.sqrt(var + (Z_FLOOR_ABS + Z_FLOOR_REL * np.abs(reference)) ** 2)
    p = erfc(np.abs(diff / sigma) / np.sqrt(2.0))
    threshold = Z_TEST_ALPHA / p.size
    rejected = int((p < threshold).sum())
    return ZTest(passed=rejected == 0, min_p=float(p.min()), threshold=threshold, rejected=rejected)


def convergence_slope(spps: list[int], errors: list[float]) -> float:
    """Least-squares slope of log(error) against log(spp): about -0.5 for an unbiased Monte Carlo
    estimator whose error is dominated by its own noise."""
    x, y = np.log(np.asarray(spps, float)), np.log(np.maximum(np.asarray(errors, float), 1e-30))
    return float(np.polyfit(x, y, 1)[0])
