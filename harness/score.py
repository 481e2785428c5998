"""Image scores of the regression harness: SSIM, RMSE, max error, a per-pixel Z-test, a bias test
of region means, convergence.

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
from scipy.special import erfc, ndtri
from skimage.metrics import structural_similarity

from wrt.errors import WrtError
from wrt.imageio import srgb_encode

SSIM_DATA_RANGE = 1.0  # tone-mapped images live in [0, 1]
SSIM_WINDOW = 7  # scikit-image's window: images smaller than 7 x 7 have no SSIM
Z_TEST_ALPHA = 0.01  # family-wise significance level of the per-pixel test
# Standard deviation floor of the Z-test: float32 rounding and CPU/CUDA differences make even a
# noise-free render differ from its reference by this much (absolute + relative to the value).
Z_FLOOR_ABS = 1e-4
Z_FLOOR_REL = 1e-3
# A block's variance is the largest of its neighbourhood's: a sliver of a bright object that the
# reference's samples rarely or never hit sits next to pixels whose variance shows the edge.
VARIANCE_NEIGHBOURHOOD = 5
BIAS_ALPHA = 1e-3  # family-wise false-alarm level of the bias test (regions x channels)
BIAS_GRID = 4  # the bias test's regions: the whole image and a BIAS_GRID x BIAS_GRID grid over it
# Standard deviation floor of a region mean, relative to the reference's: the reference is stored
# in half floats (11-bit significand), whose rounding is the same in every pixel of a flat region.
BIAS_FLOOR_REL = 5e-4
BIAS_FLOOR_ABS = 1e-6


def check_threshold(value, name: str) -> float:
    """``value`` as a float if it is a usable SSIM threshold, else a ``WrtError`` naming ``name``
    (the file and key, or the option) and the value.

    The one check of every threshold the harness reads: a calibration's ``ssim_threshold``, a
    feature's ``geometry_threshold``, ``wrt compare --threshold``. A threshold must be a finite
    number in [-1, 1], SSIM's range: ``-inf`` or anything under -1 would pass every image, NaN
    (``score >= nan`` is false, ``score < nan`` too) would fail or pass every image depending on
    how the comparison is written, and anything over 1 would fail every image.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not -1.0 <= value <= 1.0:
        raise WrtError(f"{name} = {value!r}: must be a finite number in [-1, 1] (the range of SSIM)")
    return float(value)


def check_spp(value, name: str) -> int:
    """``value`` (an int, or its decimal text as PNG metadata stores it) as an int >= 1, else a
    ``WrtError`` naming ``name`` and the value: the Z-test divides by the spp."""
    if isinstance(value, str) and value.strip().isdigit():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise WrtError(f"{name} = {value!r}: must be a whole number of samples >= 1")
    return value


def image_problem(rgb: np.ndarray, variance: np.ndarray | None = None) -> str | None:
    """What makes an image unfit to be scored, or None when it is clean: NaN or Inf values in the
    RGB or the variance (SSIM would count a NaN pixel as black, the Z-test would skip it), or a
    negative variance (the Z-test would clamp it to 0)."""
    problems = []
    for name, values in (("RGB", rgb), ("variance", variance)):
        if values is None:
            continue
        values = np.asarray(values)
        counts = [(np.isnan(values).sum(), "NaN"), (np.isinf(values).sum(), "Inf")]
        if name == "variance":
            counts.append(((values < 0).sum(), "negative"))
        found = [f"{int(n)} {what}" for n, what in counts if n]
        if found:
            problems.append(f"{name} has {', '.join(found)} of {values.size} values")
    return "; ".join(problems) or None


def size_problem(shape: tuple) -> str | None:
    """Why an image of ``shape`` (H, W, ...) has no SSIM, or None."""
    if min(shape[:2]) < SSIM_WINDOW:
        return f"is {shape[1]}x{shape[0]}, smaller than the {SSIM_WINDOW}x{SSIM_WINDOW} SSIM window"
    return None


def ssim(image: np.ndarray, reference: np.ndarray) -> float:
    """SSIM of two linear RGB images (H, W, 3), at least 7 x 7, after tone mapping to sRGB in [0, 1]
    (7 x 7 Gaussian-free uniform windows, scikit-image's defaults).

    Both images must be finite (``image_problem``): tone mapping would turn a NaN pixel into black
    and score it as if it were clean; callers check their inputs and report them first.
    """
    if image.shape != reference.shape:
        raise ValueError(f"image shape {image.shape} differs from reference shape {reference.shape}")
    problem = size_problem(image.shape)
    if problem:
        raise ValueError(f"SSIM needs images of at least 7 x 7 pixels: the image {problem}")
    for name, values in (("image", image), ("reference", reference)):
        problem = image_problem(values)
        if problem:
            raise ValueError(f"SSIM of a non-finite {name}: {problem}")
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


def per_pixel(spp, shape: tuple) -> np.ndarray:
    """Samples per pixel as an (H, W, 1) float64 array: ``spp`` is one count for every pixel, or
    an (H, W) array of counts (an adaptive render's ``spp`` AOV)."""
    counts = np.asarray(spp, np.float64)
    return np.broadcast_to(counts[..., None] if counts.ndim == 2 else counts, (*shape[:2], 1))


def z_test(image: np.ndarray, spp, reference: np.ndarray, ref_variance: np.ndarray, ref_spp: int) -> ZTest:
    """Is ``image`` (a mean of ``spp`` samples per pixel: one count, or an (H, W) array of them,
    ``per_pixel``) an unbiased estimate of ``reference``?

    The test runs on 2 x 2 pixel blocks: each block mean averages 4 spp samples, which tames the
    skewed per-pixel distributions of edges and small highlights at low spp (a bias does not
    average away). ``ref_variance`` is the per-sample variance of each pixel (stored with the
    reference); a block's variance is the largest over its ``VARIANCE_NEIGHBOURHOOD``-wide
    neighbourhood of blocks (rare events the reference under-sampled sit beside edges whose
    variance shows), and its standard error ``sqrt(var/4 (mean(1/spp) + 1/ref_spp))`` (the mean
    over the block's pixels), floored by
    ``Z_FLOOR_ABS + Z_FLOOR_REL |reference|``. Every block and channel is a two-sided test; the
    family is controlled by Bonferroni (level ``Z_TEST_ALPHA / n``), so noise alone fails the
    whole image with probability under 1%, while a shifted mean fails it. A block whose p-value is
    NaN (a NaN or Inf in the image, the reference or its variance) counts as rejected: corrupt
    numbers never pass.
    """
    inverse_spp = bin2x2(1.0 / per_pixel(spp, image.shape))
    image, reference = bin2x2(image), bin2x2(reference)
    diff = image - reference
    block_var = np.maximum(bin2x2(ref_variance), 0.0) / 4.0
    block_var = maximum_filter(block_var, size=(VARIANCE_NEIGHBOURHOOD, VARIANCE_NEIGHBOURHOOD, 1), mode="nearest")
    var = block_var * (inverse_spp + 1.0 / ref_spp)
    sigma = np.sqrt(var + (Z_FLOOR_ABS + Z_FLOOR_REL * np.abs(reference)) ** 2)
    p = erfc(np.abs(diff / sigma) / np.sqrt(2.0))
    threshold = Z_TEST_ALPHA / p.size
    rejected = int(np.count_nonzero(~(p >= threshold)))  # NaN p: rejected
    return ZTest(passed=rejected == 0, min_p=float(p.min()), threshold=threshold, rejected=rejected)


def pooled(images: list[np.ndarray], spps: list) -> np.ndarray:
    """Independent renders of ``spps`` samples per pixel (counts, or (H, W) arrays of them) as one
    estimate of ``sum(spps)`` samples: their spp-weighted mean, float64."""
    counts = [per_pixel(n, images[0].shape) for n in spps]
    return sum(n * np.asarray(image, np.float64) for n, image in zip(counts, images)) / sum(counts)


def batch_variance(images: list[np.ndarray], spps: list[int]) -> np.ndarray:
    """Per-sample variance of each pixel estimated from independent renders (batches) of ``spps``
    samples: the between-batch sum of squares ``sum n_i (x_i - x)^2 / (k - 1)`` around the pooled
    mean ``x``, unbiased for any batch sizes (one-way analysis of variance). With k = 3 it has 2
    degrees of freedom: too noisy alone, but it sees this render's own rare events (a firefly in
    one batch), which the reference's batches may have missed in that pixel."""
    n = np.stack([per_pixel(spp, images[0].shape) for spp in spps])
    x = np.stack([np.asarray(i, np.float64) for i in images])
    mean = (n * x).sum(axis=0) / n.sum(axis=0)
    return (n * (x - mean) ** 2).sum(axis=0) / (len(images) - 1)


@dataclass(frozen=True)
class BiasTest:
    """Outcome of the bias test of a render's region means against a reference's."""

    passed: bool
    max_z: float  # largest |z| over regions and channels (NaN when a number is not finite)
    threshold: float  # |z| above which a region mean is rejected (Bonferroni at BIAS_ALPHA)
    worst: str  # where max_z is: "image R", "region (row 1, col 2) G", ...
    image_bias: tuple[float, float, float]  # image mean / reference's - 1, per channel


def region_sums(image: np.ndarray, grid: int = BIAS_GRID) -> tuple[np.ndarray, np.ndarray]:
    """Sums over the whole image and each cell of a ``grid`` x ``grid`` partition of it (rows of
    cells in order): ``(1 + grid**2, channels)`` float64 sums and the pixel count of each region."""
    a = np.asarray(image, np.float64)
    rows = np.array_split(np.arange(a.shape[0]), grid)
    cols = np.array_split(np.arange(a.shape[1]), grid)
    cells = [a[r[0] : r[-1] + 1, c[0] : c[-1] + 1] for r in rows for c in cols]
    sums = np.stack([a.sum(axis=(0, 1))] + [cell.sum(axis=(0, 1)) for cell in cells])
    counts = np.array([a.shape[0] * a.shape[1]] + [cell.shape[0] * cell.shape[1] for cell in cells], np.float64)
    return sums, counts


def bias_test(image: np.ndarray, spp, reference: np.ndarray, ref_variance: np.ndarray, ref_spp: int) -> BiasTest:
    """Is the mean of ``image`` (``spp`` samples per pixel: one count or an (H, W) array,
    ``per_pixel``) over the whole image and over large regions the reference's? A global or
    regional bias of 1% hides in per-pixel noise, but not in a mean over thousands of pixels and
    samples.

    With independent samples per pixel, a region mean of ``n`` pixels has the variance
    ``sum(per-sample variance (1/spp + 1/ref_spp)) / n^2``, from the reference's per-sample
    variance (its own batches: the estimate is unbiased pixel by pixel, and its error averages out
    over a region), floored by ``BIAS_FLOOR_ABS + BIAS_FLOOR_REL |mean|``. Each region and channel
    is a two-sided test, Bonferroni-corrected to ``BIAS_ALPHA`` over all of them. Pass the mean of
    as many samples as there are (``run.py`` pools the convergence renders): the test's power
    grows with them, and so does the normality of the region means it assumes. A NaN anywhere
    fails.
    """
    sums, counts = region_sums(image)
    ref_sums, _ = region_sums(reference)
    variance = np.maximum(ref_variance, 0.0)
    var_sums, _ = region_sums(variance * (1.0 / per_pixel(spp, image.shape) + 1.0 / ref_spp))
    mean, ref_mean = sums / counts[:, None], ref_sums / counts[:, None]
    var = var_sums / counts[:, None] ** 2
    z = (mean - ref_mean) / np.sqrt(var + (BIAS_FLOOR_ABS + BIAS_FLOOR_REL * np.abs(ref_mean)) ** 2)
    threshold = float(-ndtri(0.5 * BIAS_ALPHA / z.size))
    abs_z = np.where(np.isfinite(z), np.abs(z), np.inf)
    region, channel = np.unravel_index(int(np.argmax(abs_z)), z.shape)
    where = "image" if region == 0 else f"region (row {(region - 1) // BIAS_GRID}, col {(region - 1) % BIAS_GRID})"
    with np.errstate(divide="ignore", invalid="ignore"):
        image_bias = tuple(float(x) for x in mean[0] / ref_mean[0] - 1.0)
    max_z = float(abs_z.max()) if np.all(np.isfinite(z)) else float("nan")
    return BiasTest(
        passed=bool(max_z <= threshold),
        max_z=max_z,
        threshold=threshold,
        worst=f"{where} {'RGB'[channel]}",
        image_bias=image_bias,
    )


def convergence_slope(spps: list[int], errors: list[float]) -> float:
    """Least-squares slope of log(error) against log(spp): about -0.5 for an unbiased Monte Carlo
    estimator whose error is dominated by its own noise. NaN when an error is NaN or Inf."""
    if not np.all(np.isfinite(errors)):
        return float("nan")
    x, y = np.log(np.asarray(spps, float)), np.log(np.maximum(np.asarray(errors, float), 1e-30))
    return float(np.polyfit(x, y, 1)[0])
