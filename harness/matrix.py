"""The feature matrix: one entry per renderer feature, read from a features file: wrt's own is
``harness/features.toml``; a project's own is any file of the same form (``wrt matrix --features``).

Each entry names its scene (a TOML file, relative to the features file), the integrator, image
size, spp and seed it is tested at, the spp of its reference, the SSIM threshold of its geometry
oracle, optionally the exact mean of its image where a closed form gives it (``closed_form_mean``,
checked by ``harness.closed_form``), and a deliberately wrong variant that must fail (the
harness's own sensitivity check). A new feature is one new entry and one scene file. Scenes are
patched in memory with ``set`` tables whose keys are paths into the scene document:

- ``render.max_depth``, ``camera.fov``: a key of a table;
- ``shape[2].center``, ``light[0].position``: a key of the i-th entry of an array of tables;
- ``material[glass].ior``: a key of the array entry whose ``name`` is ``glass``;
- ``light``: a whole table or array (``light = []`` removes every light).

Two keys test how a render is run rather than what it shows: ``passes = K`` renders the feature
in K progressive passes of equal size, and the matrix also requires the image to be bit-identical
to a one-pass render (the ``progressive`` check); ``target_error = E`` renders it with adaptive
sampling (``wrt.render(..., target_error=E)``, up to its spp), scored with each pixel's own sample
count. References are always plain one-pass renders.
"""

from __future__ import annotations

import copy
import hashlib
import importlib.util
import json
import math
import os
import re
from dataclasses import dataclass, field

from wrt.errors import WrtError
from wrt.files import read_toml
from wrt.loader import override_render, parse_scene
from wrt.renderer import ADAPTIVE_FIRST_PASS
from wrt.scene import INTEGRATORS, EnvironmentLight, Mesh, Scene

from .score import SSIM_WINDOW, check_threshold

HARNESS_DIR = os.path.dirname(os.path.abspath(__file__))
FEATURES_FILE = os.path.join(HARNESS_DIR, "features.toml")
# SSIM of the id images below which the geometry oracle disagrees: exact agreement scores 1; a
# plane's horizon (the rasteriser's plane is a finite patch) and rasteriser edge rules cost up to ~0.01
GEOMETRY_THRESHOLD = 0.98
MATRIX_SAMPLER = "independent"  # unless a feature's scene names one (see load_feature_scene)
_PATH_PART = re.compile(r"^(?P<key>[A-Za-z_]\w*)(\[(?P<sel>[^\]]+)\])?$")
# a feature's name names its reference files (NAME.exr ...) and the report's row
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
# PACKAGE:PATH scenes: files of wrt's own packages only, found without running any module's code
OWN_PACKAGES = ("wrt", "wrt_harness", "wrt_benchmarks")
_PACKAGE = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")
_KEYS = (
    "name scene integrator width height spp seed reference_spp geometry_threshold closed_form_mean passes "
    "target_error wrong"
).split()


@dataclass(frozen=True)
class Feature:
    """One matrix entry (see the module docstring and ``features.toml``)."""

    name: str
    scene: str  # absolute path
    integrator: str
    width: int
    height: int
    spp: int
    seed: int
    reference_spp: int
    geometry_threshold: float
    wrong: dict = field(default_factory=dict)  # {"description": str, "set": {path: value}}
    features_file: str = FEATURES_FILE  # the features file that lists it, as given to load_features
    closed_form_mean: tuple[float, float, float] | None = None  # the exact image mean (linear RGB), if known
    passes: int = 1  # renders in this many progressive passes (``render_feature``); > 1: checked against one pass
    target_error: float | None = None  # adaptive sampling at this target (relative standard error) at test spp

    @property
    def stochastic(self) -> bool:
        """Whether renders vary with the seed (more than one sample per pixel)."""
        return self.spp > 1


def _set_path(doc: dict, path: str, value, where: str) -> None:
    """Assign ``value`` at ``path`` (see the module docstring) inside the scene document ``doc``."""
    parts = path.split(".")
    node = doc
    for i, part in enumerate(parts):
        m = _PATH_PART.match(part)
        if not m:
            raise WrtError(f"{where}: bad path {path!r} (at {part!r})")
        key, sel = m["key"], m["sel"]
        last = i == len(parts) - 1
        if sel is None:
            if last:
                node[key] = copy.deepcopy(value)
                return
            node = node.setdefault(key, {})
            continue
        items = node.get(key)
        if not isinstance(items, list):
            raise WrtError(f"{where}: path {path!r}: no array of tables [[{key}]]")
        if sel.lstrip("-").isdigit():
            index = int(sel)
        else:
            matches = [k for k, item in enumerate(items) if item.get("name") == sel]
            if not matches:
                raise WrtError(f"{where}: path {path!r}: no [[{key}]] named {sel!r}")
            index = matches[0]
        if not -len(items) <= index < len(items):
            raise WrtError(f"{where}: path {path!r}: index {index} out of range")
        if last:
            items[index] = copy.deepcopy(value)
            return
        node = items[index]


def package_folder(package: str, where: str = "scene") -> str:
    """The folder of ``package``, one of wrt's own packages (``OWN_PACKAGES`` and their
    subpackages: ``wrt.examples``), found by ``importlib.util.find_spec`` one level at a time:
    only wrt's own packages are imported on the way (a parent's ``__init__``), never the module
    named, and never a module that is not a package (``wrt_harness.__main__`` runs a command).
    Any other name is a ``WrtError`` naming ``where``."""
    parts = package.split(".")
    if not _PACKAGE.fullmatch(package) or parts[0] not in OWN_PACKAGES:
        raise WrtError(
            f"{where}: PACKAGE:PATH names a file of wrt's own packages ({', '.join(OWN_PACKAGES)} and their "
            f"subpackages), not of {package!r}; name any other file by its path"
        )
    spec = None
    for n in range(1, len(parts) + 1):
        name = ".".join(parts[:n])
        try:
            spec = importlib.util.find_spec(name)  # imports name's parent: a package of wrt's, checked below
        except (ImportError, ValueError):
            spec = None
        if spec is None:
            raise WrtError(f"{where}: no package {name!r} in wrt")
        if spec.submodule_search_locations is None:
            raise WrtError(f"{where}: {name!r} is a module of wrt, not a package")
    return list(spec.submodule_search_locations)[0]


def scene_path(spec: str, base: str, where: str | None = None) -> str:
    """The file a feature's ``scene`` names: ``PACKAGE:PATH``, a file of one of wrt's own packages
    (``wrt.examples:path/cornell_box.toml``: wrt's example scenes; ``package_folder``), or a path
    relative to the features file's folder ``base``. ``where`` names the key in errors."""
    package, sep, rest = spec.partition(":")
    if sep and re.fullmatch(r"[A-Za-z_][\w.]*", package):
        folder = package_folder(package, f"{where or 'scene'} = {spec!r}")
        return os.path.normpath(os.path.join(folder, rest))
    return os.path.normpath(os.path.join(base, spec))


def load_features(path: str = FEATURES_FILE) -> list[Feature]:
    """All entries of the features file ``path``, in file order. A missing or malformed file, an
    entry that is not a table, lacks a key, has an unknown one, a value of the wrong type or out of
    range, names a scene file that does not exist or an unknown integrator, or a duplicate name is a
    ``WrtError`` naming the file, the entry and the key."""
    doc = read_toml(path, "features")
    base = os.path.dirname(os.path.abspath(path))
    entries = doc.get("feature")
    if entries is None:
        raise WrtError(f"{path}: no [[feature]] tables")
    if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
        raise WrtError(f"{path}: feature = {entries!r}: must be one or more [[feature]] tables")
    features = []
    for i, entry in enumerate(entries):
        where = f"{path}: feature[{i}]"

        def integer(key, default=None, least=1):
            """``entry[key]``: an integer (not a float, not a bool) >= ``least``."""
            value = entry[key] if default is None else entry.get(key, default)
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise WrtError(f"{where}.{key} = {value!r}: must be an integer >= {least}")
            return value

        def text(key, allowed=None):
            """``entry[key]``: a string (one of ``allowed``, if given)."""
            value = entry[key]
            if not isinstance(value, str) or (allowed and value not in allowed):
                raise WrtError(
                    f"{where}.{key} = {value!r}: must be " + (f"one of {', '.join(allowed)}" if allowed else "a string")
                )
            return value

        unknown = sorted(set(entry) - set(_KEYS))
        if unknown:
            raise WrtError(f"{where}: unknown key {unknown[0]!r} (known: {', '.join(_KEYS)})")
        try:
            name = text("name")
            if not _NAME.fullmatch(name):
                raise WrtError(f"{where}.name = {name!r}: must be letters, digits, '_', '.' or '-' (it names files)")
            scene = scene_path(text("scene"), base, f"{where}.scene")
            if not os.path.isfile(scene):
                raise WrtError(f"{where}.scene = {entry['scene']!r}: no such file {scene}")
            spp = integer("spp", 1)
            feature = Feature(
                name=name,
                scene=scene,
                integrator=text("integrator", INTEGRATORS),
                width=integer("width", least=SSIM_WINDOW),
                height=integer("height", least=SSIM_WINDOW),
                spp=spp,
                seed=integer("seed", 0, least=0),
                reference_spp=integer("reference_spp", 64 * spp if spp > 1 else 1),
                geometry_threshold=check_threshold(
                    entry.get("geometry_threshold", GEOMETRY_THRESHOLD), f"{where}.geometry_threshold"
                ),
                wrong=_wrong_variant(entry.get("wrong", {}), f"{where}.wrong"),
                features_file=path,
                closed_form_mean=_closed_form_mean(entry.get("closed_form_mean"), f"{where}.closed_form_mean"),
                passes=integer("passes", 1),
                target_error=_target_error(entry.get("target_error"), f"{where}.target_error"),
            )
            if spp % feature.passes:
                raise WrtError(f"{where}.passes = {feature.passes}: must divide spp = {spp} (passes of equal size)")
            if feature.target_error is not None and spp < 2 * ADAPTIVE_FIRST_PASS:
                raise WrtError(
                    f"{where}.target_error: needs spp >= {2 * ADAPTIVE_FIRST_PASS} (adaptive sampling first takes "
                    f"{ADAPTIVE_FIRST_PASS} samples everywhere), not {spp}"
                )
        except KeyError as e:
            raise WrtError(f"{where}: missing key {e.args[0]!r}") from None
        features.append(feature)
    names = [f.name for f in features]
    duplicates = {n for n in names if names.count(n) > 1}
    if duplicates:
        raise WrtError(f"{path}: duplicate feature names: {', '.join(sorted(duplicates))}")
    return features


def _target_error(value, where: str) -> float | None:
    """A feature's ``target_error``: None (not given), or a finite number in (0, 1)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 < value < 1.0:
        raise WrtError(f"{where} = {value!r}: must be a number in (0, 1) (a relative standard error)")
    return float(value)


def _closed_form_mean(value, where: str) -> tuple[float, float, float] | None:
    """A feature's ``closed_form_mean``: None (not given), or [r, g, b], three finite numbers >= 0."""
    if value is None:
        return None
    if not (
        isinstance(value, list)
        and len(value) == 3
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) and 0.0 <= v < math.inf for v in value)
    ):
        raise WrtError(f"{where} = {value!r}: must be [r, g, b], three finite numbers >= 0 (linear radiance)")
    return tuple(float(v) for v in value)


def _wrong_variant(wrong, where: str) -> dict:
    """A feature's ``wrong`` table: ``{}`` (none), or a ``description`` string and a non-empty
    ``set`` table of patches."""
    if wrong == {}:
        return {}
    if not isinstance(wrong, dict) or set(wrong) != {"description", "set"}:
        raise WrtError(f"{where} = {wrong!r}: must be a table with keys description and set")
    if not isinstance(wrong["description"], str):
        raise WrtError(f"{where}.description = {wrong['description']!r}: must be a string")
    if not isinstance(wrong["set"], dict) or not wrong["set"]:
        raise WrtError(f"{where}.set = {wrong['set']!r}: must be a table of one or more patches")
    return wrong


def select(features: list[Feature], names: list[str]) -> list[Feature]:
    """The features called ``names`` (all when empty); an unknown name is a ``WrtError``."""
    if not names:
        return features
    by_name = {f.name: f for f in features}
    unknown = [n for n in names if n not in by_name]
    if unknown:
        raise WrtError(f"unknown feature {unknown[0]!r} (known: {', '.join(by_name)})")
    return [by_name[n] for n in names]


def scene_document(feature: Feature, wrong: bool = False) -> dict:
    """The feature's scene as a TOML document with its render settings (and, if ``wrong``, the
    wrong variant's patches) applied."""
    doc = read_toml(feature.scene, "scene")
    render = doc.setdefault("render", {})
    render.update(
        integrator=feature.integrator, width=feature.width, height=feature.height, spp=feature.spp, seed=feature.seed
    )
    if wrong:
        if not feature.wrong.get("set"):
            raise WrtError(f"feature {feature.name!r} has no wrong variant")
        for path, value in feature.wrong["set"].items():
            _set_path(doc, path, value, f"{feature.features_file}: feature {feature.name!r} wrong.set")
    return doc


def load_feature_scene(feature: Feature, wrong: bool = False) -> Scene:
    """The validated scene of a feature (or of its wrong variant), with the ``MATRIX_SAMPLER``
    unless the scene names a sampler: the Z-test (``harness.score.z_test``) scales a reference's
    per-sample variance by 1/spp, which holds for independent samples, not for the faster
    convergence of the default (sobol) on smooth pixels."""
    doc = scene_document(feature, wrong)
    scene = parse_scene(doc, file=feature.scene, scene_dir=os.path.dirname(feature.scene))
    if "sampler" not in doc["render"]:
        scene = override_render(scene, source=f"feature {feature.name!r}", sampler=MATRIX_SAMPLER)
    return scene


def scene_hash(feature: Feature) -> str:
    """SHA-256 of everything a reference depends on: the scene document (without spp and seed),
    the bytes of its mesh files and environment maps, the image size and the reference spp."""
    doc = scene_document(feature)
    for key in ("spp", "seed"):
        doc["render"].pop(key)
    h = hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode())
    h.update(f"{feature.width}x{feature.height}@{feature.reference_spp}".encode())
    scene = load_feature_scene(feature)
    for item in (*scene.shapes, *scene.lights):
        if isinstance(item, Mesh) or (isinstance(item, EnvironmentLight) and item.image is not None):
            with open(item.file, "rb") as f:
                h.update(hashlib.sha256(f.read()).digest())
    return h.hexdigest()
