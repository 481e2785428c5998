"""FLIP, NVIDIA's perceptual difference metric, of a render against its reference: mean errors and
per-pixel error maps, through the package ``flip-evaluator`` (``flip_evaluator.evaluate``).

- HDR-FLIP on the linear RGB values (the EXR's radiance, negative values clipped to 0, as FLIP
  takes only non-negative HDR input): FLIP tone-maps both images with the ACES tone mapper at a
  range of exposures, from ``startExposure`` to ``stopExposure``, both computed from the
  reference, and keeps each pixel's largest LDR-FLIP error. It sees values above 1, which the
  sRGB tone map clips: emitters, highlights, their reflections. Where the reference's brightest
  luminance is within 0.1% of its median (floored at float32's epsilon, as the package does),
  the package's range is empty or reversed by rounding and it ends the process: black, constant
  or nearly black references. There the range is the one exposure that takes the brightest
  luminance (the reference's, or the image's when the reference is black) to 0.85
  (``_exposures``), the package's own choice for a constant reference; two black images score 0.
- LDR-FLIP on the tone-mapped sRGB images SSIM scores (``score.srgb_encode``: clip to [0, 1],
  sRGB curve), given to FLIP as sRGB.

Viewing conditions and tone mapper are the package's defaults, passed explicitly
(``FLIP_PARAMETERS``): a 0.7 m wide display of 3840 pixels seen from 0.7 m, 67.02 pixels per
degree of visual angle; ACES for HDR-FLIP. A FLIP error is in [0, 1], 0 for identical images;
lower is better. The harness's pass criterion is HDR-FLIP (``FLIP_CRITERION``, see
docs/harness.md).

FLIP runs on one thread (``_OPENMP``): the harness renders features side by side and ``pytest -n``
shares the cores, and there the package's OpenMP team, one thread per core, spins against the
other work: HDR-FLIP of a 96x96 render took 2 to 4 s instead of 0.3 s on 2 busy cores.

References
----------
P. Andersson, J. Nilsson, T. Akenine-Moller, M. Oskarsson, K. Astrom, M. D. Fairchild,
"FLIP: A Difference Evaluator for Alternating Images", Proc. ACM CGIT 3(2), 2020.
P. Andersson, J. Nilsson, P. Shirley, T. Akenine-Moller, "Visualizing Errors in Rendered High
Dynamic Range Images", Eurographics Short Papers, 2021.
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from pathlib import Path

import flip_evaluator
import numpy as np

from wrt.errors import WrtError
from wrt.imageio import srgb_decode

from .score import srgb_encode

FLIP_CRITERION = "hdr"  # the FLIP a feature must pass: its threshold is the calibration's flip_threshold
# viewing conditions: distance to the display (m), its width (pixels), its width (m); HDR tone mapper
FLIP_PARAMETERS = {"vc": [0.7, 3840, 0.7], "tonemapper": "ACES"}
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # linear sRGB to luminance Y, as FLIP computes it
# The luminance FLIP's ACES tone mapper (after its 0.6 pre-exposure) takes to 0.85, the value its
# exposure range gives the reference's brightest (start) and median (stop) luminance.
ACES_TARGET = 2.1188723239873153
FLAT = 1e-3  # a reference whose brightest luminance is within this of its median is flat
MEDIAN_FLOOR = float(np.finfo(np.float32).eps)  # FLIP floors the median luminance at this


def _openmp() -> ctypes.CDLL | None:
    """The OpenMP runtime the flip-evaluator wheel bundles (``flip_evaluator.libs/libgomp-*``),
    already loaded by ``flip_evaluator``; None where the package uses another."""
    found = sorted((Path(flip_evaluator.__file__).parent.parent / "flip_evaluator.libs").glob("libgomp*"))
    return ctypes.CDLL(str(found[0])) if found else None


_OPENMP = _openmp()


@dataclass(frozen=True)
class Flip:
    """Mean HDR-FLIP and LDR-FLIP of an image against a reference, and their per-pixel maps (H, W)."""

    hdr: float
    ldr: float
    hdr_map: np.ndarray
    ldr_map: np.ndarray

    @property
    def criterion(self) -> float:
        """The mean FLIP that is the pass criterion (``FLIP_CRITERION``)."""
        return self.hdr if FLIP_CRITERION == "hdr" else self.ldr


def _inputs(image: np.ndarray, reference: np.ndarray, dynamic_range: str) -> tuple[np.ndarray, np.ndarray]:
    """The (reference, test) arrays FLIP takes: HDR linear RGB clipped at 0, or LDR sRGB in [0, 1]."""
    tone_map = srgb_encode if dynamic_range == "LDR" else (lambda rgb: np.maximum(rgb, 0.0))
    return tuple(np.ascontiguousarray(tone_map(np.asarray(x, np.float64)), np.float32) for x in (reference, image))


def _exposures(reference_in: np.ndarray, image_in: np.ndarray) -> dict | None:
    """The HDR-FLIP exposure range (log2 stops) where the package cannot compute it from a flat or
    black reference, {} where it can (its own range), None where both images are black."""
    y = reference_in @ LUMINANCE
    brightest = float(y.max())
    if brightest > (1.0 + FLAT) * max(float(np.median(y)), MEDIAN_FLOOR):
        return {}
    brightest = brightest or float((image_in @ LUMINANCE).max())
    if brightest <= 0.0:
        return None
    exposure = math.log2(ACES_TARGET / brightest)
    return {"startExposure": exposure, "stopExposure": exposure, "numExposures": 2}


def _evaluate(image: np.ndarray, reference: np.ndarray, dynamic_range: str, magma: bool) -> tuple[np.ndarray, float]:
    reference_in, image_in = _inputs(image, reference, dynamic_range)
    exposures = _exposures(reference_in, image_in) if dynamic_range == "HDR" else {}
    if exposures is None:  # two black images: no error (the magma map of 0 is black)
        return np.zeros(reference_in.shape[:2] + (3 if magma else 1,), np.float32), 0.0
    if _OPENMP is not None:
        _OPENMP.omp_set_num_threads(1)  # a setting of the calling thread
    error_map, mean, _ = flip_evaluator.evaluate(
        reference_in, image_in, dynamic_range, applyMagma=magma, parameters={**FLIP_PARAMETERS, **exposures}
    )
    return error_map, float(mean)


def flip(image: np.ndarray, reference: np.ndarray) -> Flip:
    """HDR-FLIP and LDR-FLIP of ``image`` against ``reference``, both linear RGB (H, W, 3) of one size.

    Both must be finite (``score.image_problem``): callers check and report their inputs first.
    """
    if image.shape != reference.shape:
        raise ValueError(f"image shape {image.shape} differs from reference shape {reference.shape}")
    hdr_map, hdr = _evaluate(image, reference, "HDR", magma=False)
    ldr_map, ldr = _evaluate(image, reference, "LDR", magma=False)
    return Flip(hdr=hdr, ldr=ldr, hdr_map=hdr_map[..., 0], ldr_map=ldr_map[..., 0])


def error_map_image(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """The per-pixel FLIP of the pass criterion (``FLIP_CRITERION``) in the package's magma colour
    map (black 0, pale yellow 1), as linear RGB (H, W, 3) for ``write_image``."""
    srgb, _ = _evaluate(image, reference, FLIP_CRITERION.upper(), magma=True)
    return srgb_decode(np.asarray(srgb, np.float64)).astype(np.float32)


def check_flip_threshold(value, name: str) -> float:
    """``value`` as a float if it is a usable FLIP threshold, else a ``WrtError`` naming ``name``
    (the file and key, or the option) and the value: a finite number >= 0 (NaN would fail or pass
    every image depending on how the comparison is written, a negative one fail every image)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise WrtError(f"{name} = {value!r}: must be a finite number >= 0 (FLIP is an error in [0, 1])")
    return float(value)
