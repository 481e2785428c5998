"""Converting Mitsuba's sensor, film, reconstruction filter, sampler and integrator into wrt's
``[camera]`` and ``[render]`` tables."""

from __future__ import annotations

import math

import numpy as np

from .transforms import as_list, mirrors, vertical_fov
from .xml import Document, Element, Plugin, parse_number

MAX_DEPTH = 1024
"""wrt's largest ``max_depth``: what Mitsuba's ``max_depth = -1`` (unbounded) becomes."""

FILTERS = {"box": ("radius", 0.5), "gaussian": ("stddev", 0.5), "tent": ("radius", 1.0)}
"""Mitsuba reconstruction filters wrt has, with the parameter that sets their width and the
default width (pixels) that wrt's filter of the same name assumes."""

SAMPLERS = {
    "independent": "independent",
    "stratified": "stratified",
    "multijitter": "stratified",
    "orthogonal": "stratified",
    "ldsampler": "sobol",
}
"""Mitsuba sampler -> wrt ``[render] sampler``. Samplers change the noise, not the expected image."""


def sensor(doc: Document, element: Element) -> tuple[dict, dict]:
    """``(render, camera)`` tables from a ``perspective`` or ``thinlens`` sensor with its film and sampler."""
    p = Plugin(doc, element)
    if p.type not in ("perspective", "thinlens"):
        raise doc.error(element, "only perspective and thinlens sensors can be converted")
    films = p.children("film")
    render = film(doc, films[0] if films else Element("film", {"type": "hdrfilm"}, element.line))
    samplers = p.children("sampler")
    render.update(sampler(doc, samplers[0] if samplers else Element("sampler", {"type": "independent"}, element.line)))

    if p.has("fov") and p.has("focal_length"):
        raise doc.error(element, "give either fov or focal_length, not both")
    if p.has("fov"):
        fov, axis = p.number("fov", None, above=0.0, below=180.0), p.string("fov_axis", "x")
        source, name = p.params["fov"], "fov"
    else:  # 35 mm film equivalent focal length -> diagonal fov (Mitsuba's default: 50mm)
        text = p.string("focal_length", "50mm")
        source, name = p.params.get("focal_length", element), "focal_length"
        try:
            focal = parse_number(text.strip().removesuffix("mm"))
        except ValueError as e:
            raise doc.error(source, f"'focal_length' = {text!r} {e} (it must be of the form <x>mm)") from None
        if not focal > 0:
            raise doc.error(source, f"'focal_length' = {text!r} must be > 0 mm")
        fov, axis = math.degrees(2 * math.atan(math.hypot(36.0, 24.0) / (2 * focal))), "diagonal"
    try:
        fov = vertical_fov(fov, axis, render["width"], render["height"])
    except ValueError as e:
        raise doc.error(element, str(e)) from None
    if not 0.0 < fov < 180.0:  # a fov just inside (0, 180), or a tiny focal length, rounded to an end
        value = source.attrs.get("value", "")
        raise doc.error(source, f"'{name}' = {value!r} gives a vertical field of view of {fov:g} degrees")

    matrix, lookat = p.transform("to_world")
    camera = camera_pose(doc, element, matrix, lookat)
    camera["fov"] = fov
    for name in ("near_clip", "far_clip"):
        if p.has(name):
            doc.warn(p.params[name], f"'{name}' is ignored: wrt cameras have no clip planes")
    far_clip = p.number("far_clip", 1e4)
    for name in ("principal_point_offset_x", "principal_point_offset_y"):
        if p.number(name, 0.0) != 0.0:
            doc.warn(p.params[name], f"'{name}' is not supported: the principal point stays at the image centre")
    if p.has("shutter_open") or p.has("shutter_close"):
        camera["shutter"] = [p.number("shutter_open", 0.0), p.number("shutter_close", 0.0)]
    if p.type == "thinlens":
        if not p.has("aperture_radius"):
            raise doc.error(element, "a thinlens sensor needs aperture_radius")
        camera["aperture_radius"] = p.number("aperture_radius", None)
        camera["focus_distance"] = p.number("focus_distance", far_clip)  # Mitsuba's default: far_clip
    p.finish()
    return render, camera


def camera_pose(doc: Document, element: Element, matrix: np.ndarray, lookat) -> dict:
    """origin / look_at / up from a camera-to-world matrix (local +z forward, +y up)."""
    basis = matrix[:3, :3]
    norms = np.linalg.norm(basis, axis=0)
    if np.any(np.abs(norms - 1.0) > 1e-4):
        doc.warn(element, "the to_world transform scales (Mitsuba refuses this): its scale is dropped")
    if mirrors(basis):
        doc.warn(element, "the to_world transform mirrors the image (negative determinant): wrt renders it unmirrored")
    if lookat is not None:
        origin, target, up = lookat
        up = up if np.any(up) else matrix[:3, 1]
        return {"origin": as_list(origin), "look_at": as_list(target), "up": as_list(up)}
    origin = matrix[:3, 3]
    return {
        "origin": as_list(origin),
        "look_at": as_list(origin + basis[:, 2] / norms[2]),
        "up": as_list(basis[:, 1] / norms[1]),
    }


def film(doc: Document, element: Element) -> dict:
    """``width``, ``height`` and ``filter`` of the ``[render]`` table from an ``hdrfilm``."""
    p = Plugin(doc, element)
    if p.type != "hdrfilm":
        doc.warn(element, "converted as an hdrfilm")
    render = {"width": p.number("width", 768, integer=True), "height": p.number("height", 576, integer=True)}
    if render["width"] < 1 or render["height"] < 1:
        raise doc.error(element, "width and height must be positive")
    for name in ("crop_offset_x", "crop_offset_y", "crop_width", "crop_height"):
        if p.has(name):
            doc.warn(p.params[name], "crop windows are not supported: the whole film is rendered")
            p.number(name, 0, integer=True)
    if p.boolean("sample_border", False):
        doc.warn(p.params["sample_border"], "'sample_border' is not supported")
    filters = p.children("rfilter")
    render["filter"] = rfilter(doc, filters[0]) if filters else "gaussian"  # Mitsuba's default
    p.finish()
    return render


def rfilter(doc: Document, element: Element) -> str:
    """wrt's ``[render] filter`` name for a reconstruction filter."""
    p = Plugin(doc, element)
    if p.type not in FILTERS:
        doc.warn(element, "filter not supported: converted as gaussian (Mitsuba's default)")
        return "gaussian"
    width_name, width = FILTERS[p.type]
    if p.number(width_name, width) != width:
        doc.warn(p.params[width_name], f"wrt's {p.type} filter has {width_name} {width:g} pixels: value ignored")
    p.finish()
    return p.type


def sampler(doc: Document, element: Element) -> dict:
    """``spp``, ``seed`` and ``sampler`` of the ``[render]`` table."""
    p = Plugin(doc, element)
    count = p.number("sample_count", 4, integer=True)
    if count < 1:
        raise doc.error(element, "sample_count must be positive")
    if p.type not in SAMPLERS:
        doc.warn(element, "sampler not supported: converted as independent")
    if p.type == "stratified":
        count = math.ceil(math.sqrt(count)) ** 2  # Mitsuba rounds up to a square
        if not p.boolean("jitter", True):
            doc.warn(p.params["jitter"], "jitter = false (pixel-grid samples) is not supported: samples are jittered")
    render = {"spp": count, "seed": p.number("seed", 0, integer=True), "sampler": SAMPLERS.get(p.type, "independent")}
    p.finish()
    return render


def integrator(doc: Document, element: Element | None) -> dict:
    """``integrator`` and ``max_depth`` of the ``[render]`` table (Mitsuba's ``path``)."""
    if element is None:
        return {"integrator": "path", "max_depth": MAX_DEPTH}
    p = Plugin(doc, element)
    if p.type not in ("path", "volpath"):
        doc.warn(element, "integrator not supported: converted as path")
        return {"integrator": "path", "max_depth": MAX_DEPTH}
    depth = p.number("max_depth", -1, integer=True)
    if p.boolean("hide_emitters", False):
        doc.warn(p.params["hide_emitters"], "hide_emitters is not supported: emitters stay visible")
    if depth == 0:
        doc.warn(p.params["max_depth"], "max_depth = 0 (a black image) becomes 1")
    p.finish()
    return {"integrator": "path", "max_depth": MAX_DEPTH if depth < 0 else min(max(depth, 1), MAX_DEPTH)}
