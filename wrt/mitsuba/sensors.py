"""Converting Mitsuba's sensor, film, reconstruction filter, sampler and integrator into wrt's
``[camera]`` and ``[render]`` tables."""

from __future__ import annotations

import math

import numpy as np

from ..errors import token
from ..limits import MAX_DEPTH, MAX_MAGNITUDE
from .media import Media
from .transforms import as_list, mirrors, vertical_fov
from .xml import Document, Element, Plugin, parse_number

SENSORS = ("perspective", "thinlens", "orthographic")

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


def sensor(doc: Document, element: Element, media: Media) -> tuple[dict, dict]:
    """``(render, camera)`` tables from a ``perspective``, ``thinlens`` or ``orthographic`` sensor
    with its film, sampler and the medium it is in."""
    p = Plugin(doc, element)
    if p.type not in SENSORS:
        raise doc.error(element, f"only {', '.join(SENSORS)} sensors can be converted")
    films = p.children("film")
    render = film(doc, films[0] if films else Element("film", {"type": "hdrfilm"}, element.line))
    samplers = p.children("sampler")
    render.update(sampler(doc, samplers[0] if samplers else Element("sampler", {"type": "independent"}, element.line)))
    matrix, lookat = p.transform("to_world")
    camera = camera_pose(doc, element, matrix, lookat)
    if p.type == "orthographic":
        film_scale, depth_scale = orthographic_scales(doc, element, matrix[:3, :3])
        camera.update(type="orthographic", width=2.0 * film_scale)  # the film spans [-1, 1] before to_world
    else:
        if np.abs(matrix[:3, :3] @ matrix[:3, :3].T - np.eye(3)).max() > 1e-3:  # Mitsuba's Transform::has_scale
            raise doc.error(element, f"the to_world transform scales: Mitsuba refuses this for a {p.type} sensor")
        depth_scale = 1.0
        camera["fov"] = perspective_fov(doc, element, p, render)
        for name in ("principal_point_offset_x", "principal_point_offset_y"):
            if p.number(name, 0.0) != 0.0:
                doc.warn(p.params[name], f"'{name}' is not supported: the principal point stays at the image centre")

    # Clip planes: Mitsuba measures them along the view from the camera plane, as wrt does; an
    # orthographic camera starts its rays at to_world(x, y, near_clip) (depth scaled by to_world)
    # and traces them for far_clip - near_clip
    near_clip = p.number("near_clip", 1e-2, above=0.0)  # Mitsuba's defaults
    far_clip = p.number("far_clip", 1e4)
    if not far_clip > near_clip:
        raise doc.error(
            p.params.get("far_clip", element),
            f"'far_clip' = {far_clip:g} must be greater than 'near_clip' = {near_clip:g}",
        )
    camera["near_clip"] = near_clip * depth_scale
    if far_clip < MAX_MAGNITUDE:  # else no clip: nothing of a scene wrt takes is that far
        camera["far_clip"] = far_clip + near_clip * (depth_scale - 1.0)

    if p.has("shutter_open") or p.has("shutter_close"):
        camera["shutter"] = [p.number("shutter_open", 0.0), p.number("shutter_close", 0.0)]
    if p.type == "thinlens":
        if not p.has("aperture_radius"):
            raise doc.error(element, "a thinlens sensor needs aperture_radius")
        camera["aperture_radius"] = p.number("aperture_radius", None)
        camera["focus_distance"] = p.number("focus_distance", far_clip)  # Mitsuba's default: far_clip
    inside = media.refs(p, (None,))
    if inside:
        camera["medium"] = next(iter(inside.values()))
    p.finish()
    return render, camera


def perspective_fov(doc: Document, element: Element, p: Plugin, render: dict) -> float:
    """wrt's vertical ``fov`` (degrees) of a perspective or thinlens sensor: its ``fov`` along
    ``fov_axis``, or its ``focal_length``, on the film of ``render``'s size."""
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
            raise doc.error(source, f"'focal_length' = {token(text)} {e} (it must be of the form <x>mm)") from None
        if not focal > 0:
            raise doc.error(source, f"'focal_length' = {token(text)} must be > 0 mm")
        fov, axis = math.degrees(2 * math.atan(math.hypot(36.0, 24.0) / (2 * focal))), "diagonal"
    try:
        fov = vertical_fov(fov, axis, render["width"], render["height"])
    except ValueError as e:
        raise doc.error(element, str(e)) from None
    if not 0.0 < fov < 180.0:  # a fov just inside (0, 180), or a tiny focal length, rounded to an end
        value = source.attrs.get("value", "")
        raise doc.error(source, f"'{name}' = {token(value)} gives a vertical field of view of {fov:g} degrees")
    return fov


def orthographic_scales(doc: Document, element: Element, basis: np.ndarray) -> tuple[float, float]:
    """``(film, depth)``: the lengths to which the 3x3 ``basis`` of an orthographic sensor's
    to_world stretches the unit x and y axes (the film's; they must agree: wrt's pixels are
    square) and the z axis (the view's). Axes that are not perpendicular (a shear) are refused."""
    scales = np.linalg.norm(basis, axis=0)
    cosines = (basis.T @ basis) / np.outer(scales, scales)
    if np.abs(cosines - np.eye(3)).max() > 1e-9:
        raise doc.error(element, "the to_world transform shears the film (its x, y and z axes are not perpendicular)")
    if abs(scales[0] - scales[1]) > 1e-9 * scales[0]:
        raise doc.error(
            element,
            f"the to_world transform scales the film's x and y axes differently ({scales[0]:g} and {scales[1]:g}): "
            "wrt's orthographic camera has square pixels",
        )
    return float(scales[0]), float(scales[2])


def camera_pose(doc: Document, element: Element, matrix: np.ndarray, lookat) -> dict:
    """origin / look_at / up from a camera-to-world matrix (local +z forward, +y up), whatever the
    lengths of its axes."""
    basis = matrix[:3, :3]
    norms = np.linalg.norm(basis, axis=0)
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


INTEGRATORS = ("path", "volpath", "volpathmis", "direct", "moment", "ptracer")
"""Mitsuba integrators converted exactly: ``path``, ``volpath`` and ``volpathmis`` (wrt's path
integrator, which follows ``volpath``'s semantics in a scene with media and ``path``'s without;
the two volumetric ones converge to the same image), ``direct`` (path with ``max_depth = 2``: emitters seen
directly plus direct light), ``moment`` (its nested integrator: the moments are extra channels),
``ptracer`` (wrt's light tracer; its ``rr_depth`` and ``samples_per_pass`` change the noise and
the work's division only, and are read and dropped)."""


def integrator(doc: Document, element: Element | None) -> dict:
    """``integrator`` and ``max_depth`` of the ``[render]`` table."""
    if element is None:
        return {"integrator": "path", "max_depth": MAX_DEPTH}
    p = Plugin(doc, element)
    if p.type == "moment":
        inner = p.children("integrator")
        if len(inner) != 1:
            raise doc.error(element, "a moment integrator wraps exactly one integrator")
        p.finish()
        return integrator(doc, inner[0])
    if p.type not in INTEGRATORS:
        doc.warn(element, "integrator not supported: converted as path")
        return {"integrator": "path", "max_depth": MAX_DEPTH}
    if p.boolean("hide_emitters", False):
        doc.warn(p.params["hide_emitters"], "hide_emitters is not supported: emitters stay visible")
    if p.type == "direct":
        for name in ("shading_samples", "emitter_samples", "bsdf_samples"):  # change the noise only
            p.number(name, 1, integer=True)
        p.finish()
        return {"integrator": "path", "max_depth": 2}
    depth = p.number("max_depth", -1, integer=True)
    if depth == 0:
        doc.warn(p.params["max_depth"], "max_depth = 0 (a black image) becomes 1")
    kind = "path"
    if p.type == "ptracer":
        kind = "ptracer"
        p.number("rr_depth", 5, integer=True)
        p.number("samples_per_pass", 0, integer=True)
    p.finish()
    return {"integrator": kind, "max_depth": MAX_DEPTH if depth < 0 else min(max(depth, 1), MAX_DEPTH)}
