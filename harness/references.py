"""Reference images of the feature matrix: rendering, storing, checking and calibrating them.

Per feature, in a references folder (wrt's own: ``reference_images/``, installed with the harness;
a project's own: ``wrt matrix --refs DIR``; the functions below take it as ``refs``, None for wrt's):

- ``NAME.exr``: the converged mean (RGB, half float) and the per-sample variance of every pixel
  (``var.R/G/B``), with metadata ``wrt:scene_hash``, ``wrt:spp``, ``wrt:seed``, ``wrt:version``,
  ``wrt:date``;
- ``NAME.json``: the calibration: SSIM and FLIP (``flip.py``) of test-spp renders with several
  seeds against the reference, their spread, and the thresholds set beyond it; for a stochastic
  feature the same of those renders pooled with a 4x re-render (``rerender_*``), what the matrix
  scores after a miss;
- ``NAME.png``: a preview.

A reference is rendered in ``BATCHES`` independent batches (seeds ``REFERENCE_SEED + i``); the
spread of the batch means gives the per-sample variance, and the two halves of the batches must
agree by the per-pixel Z-test before anything is stored ("reproduces"). Each file is written
atomically, so an interrupted regeneration leaves every file old or new; a calibration that does
not belong to its reference (hash mismatch) is reported, never used.

Corrupt numbers are refused, never scored: a reference with NaN or Inf values or a negative
variance, a ``wrt:spp`` that is not a whole number >= 1, a calibration that is not JSON (or is
nested too deeply to read, or is not a regular file: ``wrt.files.read_json``), not a JSON object,
lacks ``reference_sha256``, ``ssim_threshold`` or ``flip_threshold`` (for a stochastic feature
also ``rerender_ssim_threshold`` and ``rerender_flip_threshold``), whose SSIM threshold is not
a finite number in [-1, 1] (``score.check_threshold``) or whose FLIP threshold is not a finite
number >= 0 (``flip.check_flip_threshold``) is a ``ReferenceError`` naming the file, the key and
the value.
"""

from __future__ import annotations

import datetime
import hashlib
import math
import os
import shlex
import statistics
from dataclasses import dataclass
from importlib import resources

import numpy as np

import wrt
from wrt.errors import WrtError
from wrt.files import check_writable, probe_folder, read_json, write_json
from wrt.imageio import read_image, write_image

from .flip import FLIP_CRITERION, check_flip_threshold, flip
from .matrix import FEATURES_FILE, Feature, load_feature_scene, scene_hash
from .score import check_spp, check_threshold, image_problem, pooled, ssim, z_test

REFERENCE_DIR = str(
    resources.files("wrt_harness.reference_images")
)  # the tree's reference_images/, installed with the harness
BATCHES = 32  # independent batches a reference is rendered in (variance estimate with 31 dof)
REFERENCE_SEED = 1_000_000  # reference batches use seeds from here; test renders use small seeds
CALIBRATION_SEEDS = (11, 12, 13, 14, 15, 16)
HALF_MAX = float(np.finfo(np.float16).max)  # the largest RGB value a reference EXR (half float) holds
CALIBRATION_MARGIN = 0.002  # threshold = min(SSIM) - max(CALIBRATION_MARGIN, 3 std(SSIM))
FLIP_CALIBRATION_MARGIN = 0.002  # flip_threshold = max(FLIP) + max(FLIP_CALIBRATION_MARGIN, 3 std(FLIP))
CALIBRATION_LIMIT = 1 << 20  # bytes of a calibration file read (wrt writes about 2 KB)
RERENDER_SPP = 4  # a stochastic feature that misses is rendered again at this many times its spp
RERENDER_SEED_OFFSET = 7919  # with samples independent of the first render's (and of calibration's)


def refs_command(action: str, features_file: str | None, refs: str | None, *names: str) -> str:
    """The command line ``wrt refs ACTION [--features FILE] [--refs DIR] NAME...``, with the options
    only where they are not wrt's own (None)."""
    words = ["wrt", "refs", action]
    if features_file not in (None, FEATURES_FILE):
        words += ["--features", features_file]
    if refs is not None:
        words += ["--refs", refs]
    return shlex.join([*words, *names])


class ReferenceError(WrtError):
    """A reference that is missing, unreadable or does not match its feature; the message ends
    with the command that fixes it."""

    def __init__(self, feature: Feature, problem: str, action: str = "regenerate", refs: str | None = None):
        fix = refs_command(action, feature.features_file, refs, feature.name)
        super().__init__(f"reference of {feature.name!r}: {problem}; run: {fix}")
        self.feature = feature.name


@dataclass
class Reference:
    rgb: np.ndarray  # (H, W, 3) float32, converged mean
    variance: np.ndarray  # (H, W, 3) per-sample variance
    spp: int
    metadata: dict
    calibration: dict | None


def paths(name: str, refs: str | None = None) -> dict[str, str]:
    """The reference files of feature ``name`` in the folder ``refs`` (default ``REFERENCE_DIR``)."""
    refs = refs or REFERENCE_DIR
    return {ext: os.path.join(refs, f"{name}.{ext}") for ext in ("exr", "json", "png")}


def check_storable(features: list[Feature], refs: str | None, kinds=("exr", "json", "png")) -> None:
    """``WrtError`` unless the reference files ``kinds`` of every one of ``features`` can be written
    into ``refs`` (which exists): the folder is writable and none of the files is a folder. Called
    before the renders that would fill them."""
    folder = refs or REFERENCE_DIR
    shown = f"--refs {refs}" if refs is not None else f"the references folder {folder}"
    try:
        probe_folder(folder, shown)
    except WrtError as e:
        raise WrtError(f"{e}; nothing was rendered") from None
    for feature in features:
        for kind in kinds:
            check_writable(paths(feature.name, refs)[kind])


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
    scene=None,
    as_tested: bool = True,
):
    """Render a feature's scene (or its wrong variant) at its test spp and seed unless overridden;
    ``scene``: that scene already loaded (on a cluster worker, which has no scene files).

    ``as_tested``: the way the feature says it is rendered: in ``passes`` progressive passes of
    equal size, or adaptively at ``target_error`` (scaled by ``sqrt(feature.spp / spp)`` at other
    spp, so that a render of 4x the samples aims at half the error); else one plain pass, as
    references are rendered. Samples per pixel: ``samples``."""
    scene = load_feature_scene(feature, wrong) if scene is None else scene
    options = {}
    if as_tested:
        total = spp or feature.spp
        if feature.passes > 1:
            options.update(progress=lambda *args: True, progress_every=total // feature.passes)
        if feature.target_error is not None:
            options.update(target_error=feature.target_error * math.sqrt(feature.spp / total))
    return wrt.render(scene, spp=spp, seed=seed, device=device, threads=threads, **options)


def samples(result):
    """Samples per pixel of a render: its ``spp``, or, adaptive, the (H, W) counts of its ``spp``
    AOV (``score.per_pixel`` takes either)."""
    return result.aovs["spp"] if "spp" in result.aovs else result.spp


def render_images(
    feature: Feature,
    seeds,
    spp: int | None = None,
    device: str = "cpu",
    threads: int | None = None,
    cluster=None,
    as_tested: bool = True,
) -> list[np.ndarray]:
    """The RGB render of ``feature`` (at ``spp``, default its test spp; ``as_tested``: see
    ``render_feature``) for each of ``seeds``: here, or on ``cluster`` (a
    ``wrt.distributed.Cluster``: one task each, the same images bit for bit) where the render is a
    plain one (the cluster renders whole images in one pass)."""
    plain = not as_tested or (feature.passes == 1 and feature.target_error is None)
    if cluster is not None and plain:
        return cluster.images(load_feature_scene(feature), list(seeds), spp=spp, device=device)
    return [
        render_feature(feature, spp=spp, seed=seed, device=device, threads=threads, as_tested=as_tested).rgb
        for seed in seeds
    ]


def load_reference(feature: Feature, refs: str | None = None, calibration: bool = True) -> Reference:
    """The stored reference of ``feature`` in ``refs``; ``ReferenceError`` naming the fix when it is
    missing, corrupt, of the wrong size, made from another scene, or (with ``calibration``) when its
    calibration file belongs to another reference image."""
    p = paths(feature.name, refs)
    if not os.path.exists(p["exr"]):
        raise ReferenceError(feature, f"{p['exr']} is missing", refs=refs)
    try:
        image = read_image(p["exr"])
    except WrtError as e:
        raise ReferenceError(feature, f"unreadable ({e})", refs=refs) from None
    if image.rgb.shape != (feature.height, feature.width, 3) or "variance" not in image.aovs:
        raise ReferenceError(
            feature,
            f"{p['exr']} is {image.rgb.shape[1]}x{image.rgb.shape[0]} without the expected channels, the matrix wants "
            f"{feature.width}x{feature.height}",
            refs=refs,
        )
    problem = image_problem(image.rgb, image.aovs["variance"])
    if problem:
        raise ReferenceError(feature, f"{p['exr']} is corrupt: {problem}", refs=refs)
    try:
        spp = check_spp(image.metadata.get("spp"), f"{p['exr']}: wrt:spp")
    except WrtError as e:
        raise ReferenceError(feature, str(e), refs=refs) from None
    if image.metadata.get("scene_hash") != scene_hash(feature):
        raise ReferenceError(
            feature,
            "the scene or the matrix entry changed since the reference was made (scene hash differs)",
            refs=refs,
        )
    stored = None
    if calibration and os.path.exists(p["json"]):
        try:
            stored = read_json(p["json"], "calibration", limit=CALIBRATION_LIMIT)
        except WrtError as e:  # not JSON, nested too deeply, a folder, a FIFO...: one line
            raise ReferenceError(feature, str(e), "calibrate", refs) from None
        stored = _checked_calibration(feature, stored, p["json"], p["exr"], refs)
    return Reference(
        rgb=image.rgb,
        variance=image.aovs["variance"],
        spp=spp,
        metadata=image.metadata,
        calibration=stored,
    )


_JSON_KINDS = {dict: "an object", list: "an array", str: "a string", bool: "a boolean", type(None): "null"}


def json_kind(value) -> str:
    """What the JSON value ``value`` is, in words ("an array"): messages name it, never quote a document."""
    return _JSON_KINDS.get(type(value), "a number" if isinstance(value, (int, float)) else "something else")


def _checked_calibration(feature: Feature, stored, path: str, exr: str, refs: str | None) -> dict:
    """The calibration ``stored`` (read from ``path``), with its ``ssim_threshold`` and
    ``flip_threshold`` as floats, if it is an object that belongs to the image ``exr`` and has
    usable thresholds; else a ``ReferenceError`` naming the file and the key."""
    if not isinstance(stored, dict):
        raise ReferenceError(
            feature,
            f"{path} is not a JSON object (it holds {json_kind(stored)})",
            "calibrate",
            refs,
        )
    for key in ("reference_sha256", "ssim_threshold", "flip_threshold"):
        if key not in stored:
            raise ReferenceError(feature, f"{path}: missing key {key!r}", "calibrate", refs)
    sha = stored["reference_sha256"]
    if not isinstance(sha, str):
        raise ReferenceError(
            feature, f"{path}: reference_sha256 = {sha!r}: must be the SHA-256 text of {exr}", "calibrate", refs
        )
    if sha != file_sha256(exr):
        raise ReferenceError(
            feature,
            "its calibration belongs to another reference image (run wrt refs calibrate, or regenerate)",
            refs=refs,
        )
    prefixes = ("", "rerender_") if feature.stochastic else ("",)
    checked = {}
    for prefix in prefixes:
        for key, check in (("ssim_threshold", check_threshold), ("flip_threshold", check_flip_threshold)):
            name = prefix + key
            if name not in stored:  # a calibration made before the re-render had its own thresholds
                raise ReferenceError(feature, f"{path}: missing key {name!r}", "calibrate", refs)
            try:
                checked[name] = check(stored[name], f"{path}: {name}")
            except WrtError as e:
                raise ReferenceError(feature, str(e), "calibrate", refs) from None
    return {**stored, **checked}


def render_reference(
    feature: Feature, spp: int | None = None, device: str = "cpu", threads: int | None = None, cluster=None
) -> Reference:
    """Render a converged reference in ``BATCHES`` batches (on ``cluster``: one task each, see
    ``render_images``) and check that it reproduces.

    Deterministic features (1 spp at the pixel centre) have one exact batch and zero variance.
    """
    spp = spp or feature.reference_spp
    batches = min(BATCHES, spp) if feature.stochastic else 1
    per_batch = max(1, spp // batches)
    seeds = [REFERENCE_SEED + i for i in range(batches)]
    means = np.stack(render_images(feature, seeds, per_batch, device, threads, cluster, as_tested=False)).astype(
        np.float64
    )
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


def _thresholds(feature: Feature, reference: Reference, images: list[np.ndarray], seeds, prefix: str = "") -> dict:
    """SSIM and FLIP of ``images`` (one per seed) against the reference, their spread, and the
    thresholds set beyond it: SSIM ``min - max(CALIBRATION_MARGIN, 3 std)``, FLIP (of
    ``FLIP_CRITERION``, an error) ``max + max(FLIP_CALIBRATION_MARGIN, 3 std)``; every key prefixed
    with ``prefix``."""
    scores, flips = [], []
    for seed, rgb in zip(seeds, images):
        problem = image_problem(rgb)
        if problem:
            raise WrtError(
                f"feature {feature.name!r}: the calibration render with seed {seed} is not finite: {problem}"
            )
        scores.append(ssim(rgb, reference.rgb))
        flips.append(flip(rgb, reference.rgb))
    spread = statistics.stdev(scores) if len(scores) > 1 else 0.0
    margin = max(CALIBRATION_MARGIN, 3.0 * spread)
    criterion = [f.criterion for f in flips]
    flip_spread = statistics.stdev(criterion) if len(criterion) > 1 else 0.0
    flip_margin = max(FLIP_CALIBRATION_MARGIN, 3.0 * flip_spread)
    found = {
        "ssim": scores,
        "ssim_mean": statistics.fmean(scores),
        "ssim_std": spread,
        "margin": margin,
        "ssim_threshold": min(scores) - margin,
        "hdr_flip": [f.hdr for f in flips],
        "ldr_flip": [f.ldr for f in flips],
        "flip_std": flip_spread,
        "flip_margin": flip_margin,
        "flip_threshold": max(criterion) + flip_margin,
    }
    return {prefix + key: value for key, value in found.items()}


def calibrate(
    feature: Feature, reference: Reference, device: str = "cpu", threads: int | None = None, cluster=None
) -> dict:
    """Render the feature at its test spp with ``CALIBRATION_SEEDS`` (on ``cluster``: one task
    each) and set its SSIM and FLIP thresholds beyond the spread of their scores (``_thresholds``;
    HDR- and LDR-FLIP are both recorded). A stochastic feature is also calibrated for what the
    matrix scores after a miss, the test render pooled with a re-render at ``RERENDER_SPP`` times
    its spp (seed + ``RERENDER_SEED_OFFSET``): ``rerender_ssim_threshold`` and
    ``rerender_flip_threshold``, tighter than the 1x ones, which a 5x pooled render would meet
    more easily than the render it stands in for."""
    seeds = CALIBRATION_SEEDS if feature.stochastic else CALIBRATION_SEEDS[:1]
    images = render_images(feature, seeds, device=device, threads=threads, cluster=cluster)
    calibration = {
        "feature": feature.name,
        "test_spp": feature.spp,
        "seeds": list(seeds),
        **_thresholds(feature, reference, images, seeds),
        "rule": "threshold = min(ssim) - max(0.002, 3 * std(ssim))",
        "flip_criterion": FLIP_CRITERION,
        "flip_rule": f"flip_threshold = max({FLIP_CRITERION}_flip) + max(0.002, 3 * std({FLIP_CRITERION}_flip))",
    }
    if feature.stochastic:
        spps = [feature.spp, RERENDER_SPP * feature.spp]
        again = render_images(
            feature,
            [seed + RERENDER_SEED_OFFSET for seed in seeds],
            spp=spps[1],
            device=device,
            threads=threads,
            cluster=cluster,
        )
        both = [pooled([first, second], spps) for first, second in zip(images, again)]
        calibration["rerender_spp"] = sum(spps)
        calibration.update(_thresholds(feature, reference, both, seeds, prefix="rerender_"))
    return calibration


def store(feature: Feature, reference: Reference, refs: str | None = None) -> None:
    """Write the reference EXR (half RGB, float variance) and its preview PNG into ``refs``,
    atomically each."""
    p = paths(feature.name, refs)
    write_image(p["exr"], reference.rgb, aovs={"variance": reference.variance}, metadata=reference.metadata, half=True)
    write_image(p["png"], reference.rgb)


def store_calibration(feature: Feature, calibration: dict, refs: str | None = None) -> None:
    p = paths(feature.name, refs)
    write_json(p["json"], {**calibration, "reference_sha256": file_sha256(p["exr"])})
