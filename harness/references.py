"""Reference images of the feature matrix: rendering, storing, checking and calibrating them.

Per feature, in ``reference_images/``:

- ``NAME.exr``: the converged mean (RGB, half float) and the per-sample variance of every pixel
  (``var.R/G/B``), with metadata ``wrt:scene_hash``, ``wrt:spp``, ``wrt:seed``, ``wrt:version``,
  ``wrt:date``;
- ``NAME.json``: the calibration: SSIM of test-spp renders with several seeds against the
  reference, their spread, and the threshold set under it;
- ``NAME.png``: a preview.

A reference is rendered in ``BATCHES`` independent batches (seeds ``REFERENCE_SEED + i``); the
spread of the batch means gives the per-sample variance, and the two halves of the batches must
agree by the per-pixel Z-test before anything is stored ("reproduces"). Each file is written
atomically, so an interrupted regeneration leaves every file old or new; a calibration that does
not belong to its reference (hash mismatch) is reported, never used.

Corrupt numbers are refused, never scored: a reference with NaN or Inf values or a negative
variance, a ``wrt:spp`` that is not a whole number >= 1, a calibration that is not a JSON object,
lacks ``reference_sha256`` or ``ssim_threshold``, or whose threshold is not a finite number in
[-1, 1] (``score.check_threshold``) is a ``ReferenceError`` naming the file, the key and the value.
"""

from __future__ import annotations

import datetime
import hashlib
import json
import os
import statistics
from dataclasses import dataclass
from importlib import resources

import numpy as np

import wrt
from wrt.errors import WrtError
from wrt.files import write_json
from wrt.imageio import read_image, write_image

from .matrix import Feature, load_feature_scene, scene_hash
from .score import check_spp, check_threshold, image_problem, ssim, z_test

REFERENCE_DIR = str(
    resources.files("wrt_harness.reference_images")
)  # the tree's reference_images/, installed with the harness
BATCHES = 32  # independent batches a reference is rendered in (variance estimate with 31 dof)
REFERENCE_SEED = 1_000_000  # reference batches use seeds from here; test renders use small seeds
CALIBRATION_SEEDS = (11, 12, 13, 14, 15, 16)
HALF_MAX = float(np.finfo(np.float16).max)  # the largest RGB value a reference EXR (half float) holds
CALIBRATION_MARGIN = 0.002  # threshold = min(SSIM) - max(CALIBRATION_MARGIN, 3 std(SSIM))


class ReferenceError(WrtError):
    """A reference that is missing, unreadable or does not match its feature."""

    def __init__(self, feature: str, problem: str, action: str = "regenerate"):
        super().__init__(f"reference of {feature!r}: {problem}; run: wrt refs {action} {feature}")
        self.feature = feature


@dataclass
class Reference:
    rgb: np.ndarray  # (H, W, 3) float32, converged mean
    variance: np.ndarray  # (H, W, 3) per-sample variance
    spp: int
    metadata: dict
    calibration: dict | None


def paths(name: str, folder: str | None = None) -> dict[str, str]:
    """The reference files of feature ``name`` in ``folder`` (default ``REFERENCE_DIR``)."""
    folder = folder or REFERENCE_DIR
    return {ext: os.path.join(folder, f"{name}.{ext}") for ext in ("exr", "json", "png")}


def file_sha256(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def render_feature(
    feature: Feature,
    spp: int | None = None,
    seed: int | None = None,
    wrong: bool = False,
    device: str = "cpu",
    threads: int | None = None,
):
    """Render a feature's scene (or its wrong variant) at its test spp and seed unless overridden."""
    return wrt.render(load_feature_scene(feature, wrong), spp=spp, seed=seed, device=device, threads=threads)


def load_reference(feature: Feature, folder: str | None = None, calibration: bool = True) -> Reference:
    """The stored reference of ``feature``; ``ReferenceError`` naming the fix when it is missing,
    corrupt, of the wrong size, made from another scene, or (with ``calibration``) when its
    calibration file belongs to another reference image."""
    p = paths(feature.name, folder)
    if not os.path.exists(p["exr"]):
        raise ReferenceError(feature.name, f"{p['exr']} is missing")
    try:
        image = read_image(p["exr"])
    except WrtError as e:
        raise ReferenceError(feature.name, f"unreadable ({e})") from None
    if image.rgb.shape != (feature.height, feature.width, 3) or "variance" not in image.aovs:
        raise ReferenceError(
            feature.name,
            f"{p['exr']} is {image.rgb.shape[1]}x{image.rgb.shape[0]} without the expected channels, the matrix wants "
            f"{feature.width}x{feature.height}",
        )
    problem = image_problem(image.rgb, image.aovs["variance"])
    if problem:
        raise ReferenceError(feature.name, f"{p['exr']} is corrupt: {problem}")
    try:
        spp = check_spp(image.metadata.get("spp"), f"{p['exr']}: wrt:spp")
    except WrtError as e:
        raise ReferenceError(feature.name, str(e)) from None
    if image.metadata.get("scene_hash") != scene_hash(feature):
        raise ReferenceError(
            feature.name, "the scene or the matrix entry changed since the reference was made (scene hash differs)"
        )
    stored = None
    if calibration and os.path.exists(p["json"]):
        try:
            with open(p["json"]) as f:
                stored = json.load(f)
        except (OSError, ValueError) as e:
            raise ReferenceError(feature.name, f"{p['json']} is unreadable ({e})") from None
        stored = _checked_calibration(feature, stored, p["json"], p["exr"])
    return Reference(
        rgb=image.rgb,
        variance=image.aovs["variance"],
        spp=spp,
        metadata=image.metadata,
        calibration=stored,
    )


_JSON_KINDS = {
    list: "an array",
    str: "a string",
    int: "a number",
    float: "a number",
    bool: "a boolean",
    type(None): "null",
}


def _checked_calibration(feature: Feature, stored, path: str, exr: str) -> dict:
    """The calibration ``stored`` (read from ``path``), with its ``ssim_threshold`` as a float, if
    it is an object that belongs to the image ``exr`` and has a usable threshold; else a
    ``ReferenceError`` naming the file and the key."""
    if not isinstance(stored, dict):
        raise ReferenceError(
            feature.name,
            f"{path} is not a JSON object (it holds {_JSON_KINDS.get(type(stored), 'something else')})",
            "calibrate",
        )
    for key in ("reference_sha256", "ssim_threshold"):
        if key not in stored:
            raise ReferenceError(feature.name, f"{path}: missing key {key!r}", "calibrate")
    sha = stored["reference_sha256"]
    if not isinstance(sha, str):
        raise ReferenceError(
            feature.name, f"{path}: reference_sha256 = {sha!r}: must be the SHA-256 text of {exr}", "calibrate"
        )
    if sha != file_sha256(exr):
        raise ReferenceError(
            feature.name,
            "its calibration belongs to another reference image (run wrt refs calibrate, or regenerate)",
        )
    try:
        threshold = check_threshold(stored["ssim_threshold"], f"{path}: ssim_threshold")
    except WrtError as e:
        raise ReferenceError(feature.name, str(e), "calibrate") from None
    return {**stored, "ssim_threshold": threshold}


def render_reference(
    feature: Feature, spp: int | None = None, device: str = "cpu", threads: int | None = None
) -> Reference:
    """Render a converged reference in ``BATCHES`` batches and check that it reproduces.

    Deterministic features (1 spp at the pixel centre) have one exact batch and zero variance.
    """
    spp = spp or feature.reference_spp
    batches = min(BATCHES, spp) if feature.stochastic else 1
    per_batch = max(1, spp // batches)
    means = np.stack(
        [
            render_feature(feature, spp=per_batch, seed=REFERENCE_SEED + i, device=device, threads=threads).rgb
            for i in range(batches)
        ]
    ).astype(np.float64)
    mean = means.mean(axis=0)
    total = per_batch * batches
    variance = np.zeros_like(mean)
    if batches > 1:
        # per-sample variance pooled within the two halves (disjoint seeds)
        half = batches // 2
        first, second = means[:half], means[half:]
        variance = 0.5 * (first.var(axis=0, ddof=1) + second.var(axis=0, ddof=1)) * per_batch
    problem = image_problem(mean, variance)
    if not problem and np.abs(mean).max() > HALF_MAX:  # stored as half float: it would read back as Inf
        problem = f"RGB exceeds the half-float range ({np.abs(mean).max():.3g} > {HALF_MAX:.0f})"
    if problem:
        raise WrtError(f"feature {feature.name!r}: the reference cannot be stored: {problem}; nothing was written")
    if batches > 1:
        # the halves must agree within their noise: a reference that depends on its seeds is not stored
        check = z_test(
            first.mean(axis=0), per_batch * half, second.mean(axis=0), variance, per_batch * (batches - half)
        )
        if not check.passed:
            raise WrtError(
                f"feature {feature.name!r}: the reference does not reproduce: two halves rendered with different "
                "seeds differ "
                f"beyond their noise at {check.rejected} pixel blocks (min p = {check.min_p:.2e}); nothing was written"
            )
    metadata = {
        "scene_hash": scene_hash(feature),
        "spp": total,
        "seed": REFERENCE_SEED,
        "version": wrt.__version__,
        "date": datetime.date.today().isoformat(),
    }
    return Reference(
        rgb=mean.astype(np.float32),
        variance=variance.astype(np.float32),
        spp=total,
        metadata=metadata,
        calibration=None,
    )


def calibrate(feature: Feature, reference: Reference, device: str = "cpu", threads: int | None = None) -> dict:
    """Render the feature at its test spp with ``CALIBRATION_SEEDS`` and set its SSIM threshold
    under the spread: ``min - max(CALIBRATION_MARGIN, 3 std)``."""
    seeds = CALIBRATION_SEEDS if feature.stochastic else CALIBRATION_SEEDS[:1]
    scores = []
    for seed in seeds:
        rgb = render_feature(feature, seed=seed, device=device, threads=threads).rgb
        problem = image_problem(rgb)
        if problem:
            raise WrtError(
                f"feature {feature.name!r}: the calibration render with seed {seed} is not finite: {problem}"
            )
        scores.append(ssim(rgb, reference.rgb))
    spread = statistics.stdev(scores) if len(scores) > 1 else 0.0
    margin = max(CALIBRATION_MARGIN, 3.0 * spread)
    return {
        "feature": feature.name,
        "test_spp": feature.spp,
        "seeds": list(seeds),
        "ssim": scores,
        "ssim_mean": statistics.fmean(scores),
        "ssim_std": spread,
        "margin": margin,
        "ssim_threshold": min(scores) - margin,
        "rule": "threshold = min(ssim) - max(0.002, 3 * std(ssim))",
    }


def store(feature: Feature, reference: Reference, folder: str | None = None) -> None:
    """Write the reference EXR (half RGB, float variance) and its preview PNG, atomically each."""
    p = paths(feature.name, folder)
    write_image(p["exr"], reference.rgb, aovs={"variance": reference.variance}, metadata=reference.metadata, half=True)
    write_image(p["png"], reference.rgb)


def store_calibration(feature: Feature, calibration: dict, folder: str | None = None) -> None:
    p = paths(feature.name, folder)
    write_json(p["json"], {**calibration, "reference_sha256": file_sha256(p["exr"])})
