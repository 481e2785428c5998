"""Converting Mitsuba's participating media into wrt media: ``homogeneous`` (``sigma_t``,
``albedo``, ``scale``) and ``heterogeneous`` (``sigma_t`` and ``albedo`` a ``gridvolume`` or a
``constvolume``, or one value) with its ``isotropic`` or ``hg`` phase function, each ``<medium>``
once, named when a shape's ``interior`` or ``exterior`` or the sensor first uses it. A
heterogeneous medium's plain ``sigma_t`` value is a constant volume over the unit cube, as
Mitsuba makes it. A ``volumelight`` emitter on a shape is the emission of the shape's interior
medium (``Media.emit``); a medium's ``sigma_n`` (its null density) and ``medium_sampling_mode``
change the noise only (wrt's tracking is unbiased for any bound), ``sigma_n`` kept as the null
density of a heterogeneous medium, which a clear emissive one needs."""

from __future__ import annotations

import numpy as np

from .transforms import as_list
from .xml import Document, Element, Plugin

HARMLESS_MEDIUM = ("sample_emitters",)
SAMPLING_MODES = ("analogue", "max", "mean")
"""Mitsuba's ``medium_sampling_mode`` values: how a chromatic medium's collisions are chosen, which
changes the noise only."""
HARMLESS_GRID = ("raw",)
"""Grid volume parameters of no effect in RGB: ``raw`` turns off the spectral upsampling of RGB
texels, which Mitsuba's RGB variants do not do."""
"""Medium parameters that change only the noise: whether scattering events sample the emitters
(wrt always does, MIS-weighted against the phase function: the same image)."""


class Media:
    """The ``[[medium]]`` tables of a conversion, one per ``<medium>`` element, in first-use order."""

    def __init__(self, doc: Document):
        self.doc = doc
        self.tables: list[dict] = []
        self.sources: list[Element] = []
        self._names: dict[int, str] = {}

    def name(self, element: Element) -> str:
        """The name of the ``[[medium]]`` converted from ``element`` (converted on first use)."""
        key = id(element)
        if key not in self._names:
            name = element.attrs.get("id") or f"medium@{element.line}"
            taken = {table["name"] for table in self.tables}
            while name in taken:
                name += "'"
            self._names[key] = name
            self.tables.append({"name": name, **convert(self.doc, element)})
            self.sources.append(element)
        return self._names[key]

    def emit(self, name: str, element: Element) -> None:
        """Give the ``[[medium]]`` named ``name`` the emission of the ``volumelight`` ``element``
        (its ``radiance``: a colour, or for a heterogeneous medium a volume)."""
        table = self.tables[[t["name"] for t in self.tables].index(name)]
        if "emission" in table:
            raise self.doc.error(element, f"medium {name!r} has a volumelight already: a medium emits once")
        p = Plugin(self.doc, element)
        if table["type"] == "heterogeneous":
            table["emission"] = volume(self.doc, p, "radiance", 1.0)
        else:
            if p.named("radiance", "volume") is not None:
                raise self.doc.error(
                    element, "a volume radiance needs a heterogeneous medium (this one is homogeneous)"
                )
            table["emission"] = p.color("radiance", 1.0, emission=True)
        p.finish()

    def refs(self, p: Plugin, names: tuple[str, ...]) -> dict[str, str]:
        """The media a plugin names (``interior``, ``exterior``; a sensor's any name), by the name
        it gives them, as ``[[medium]]`` names; marks them read."""
        found = {}
        for name, child in p.nested:
            if child.tag == "medium":
                p.used_nested.add(id(child))
                if name not in names and None not in names:
                    self.doc.warn(child, f"a medium named {name!r} here is not supported: ignored")
                    continue
                found[name] = self.name(child)
        return found


def convert(doc: Document, element: Element) -> dict:
    """The ``[[medium]]`` table (without its name) of a ``<medium>``."""
    p = Plugin(doc, element)
    if p.type not in ("homogeneous", "heterogeneous"):
        doc.warn(element, f"medium type {p.type!r} is not supported: converted as a homogeneous medium of its defaults")
    if p.type == "heterogeneous":
        table = {
            "type": "heterogeneous",
            "sigma_t": volume(doc, p, "sigma_t", 1.0),
            "albedo": volume(doc, p, "albedo", 0.75),
        }
    else:
        table = {
            "type": "homogeneous",
            "sigma_t": p.color("sigma_t", 1.0, unbounded=True),
            "albedo": p.color("albedo", 0.75),
        }
    table["scale"] = p.number("scale", 1.0)
    if table["scale"] < 0.0:
        raise doc.error(p.params["scale"], f"'scale' = {table['scale']:g} must not be negative")
    phases = p.children("phase")
    for extra in phases[1:]:
        doc.warn(extra, "a medium takes one phase function: ignored")
    if phases:
        table["phase"] = phase(doc, phases[0])
    if p.type in ("homogeneous", "heterogeneous"):
        sigma_n = null_density(doc, p)
        if p.type == "heterogeneous" and sigma_n > 0.0:
            table["sigma_n"] = sigma_n
        for name in HARMLESS_MEDIUM:
            p.boolean(name, True)
        mode = p.string("medium_sampling_mode", "analogue")
        if mode not in SAMPLING_MODES:
            doc.warn(p.params["medium_sampling_mode"], f"'medium_sampling_mode' = {mode!r} is not one of Mitsuba's")
        p.finish()
    return table


def null_density(doc: Document, p: Plugin) -> float:
    """A medium's ``sigma_n``: a number or a ``constvolume`` (a ``gridvolume``: its bound only
    matters, taken as 0 with a warning)."""
    element = p.named("sigma_n", "volume")
    if element is None:
        value = p.number("sigma_n", 0.0)
    else:
        p.used_nested.add(id(element))
        v = Plugin(doc, element)
        if v.type == "constvolume":
            value = max(v.color("value", 0.0, unbounded=True))
            v.transform("to_world")
            v.finish()
        else:
            doc.warn(element, "a sigma_n volume other than a constvolume is taken as 0 (it changes the noise only)")
            value = 0.0
    if value < 0.0:
        raise doc.error(p.params.get("sigma_n", element), f"'sigma_n' = {value:g} must not be negative")
    return value


def volume(doc: Document, p: Plugin, name: str, default: float) -> dict | list[float]:
    """A heterogeneous medium's ``sigma_t`` or ``albedo`` (or a ``volumelight``'s ``radiance``): its
    nested ``<volume>`` as a volume table, or its plain value (``sigma_t``'s a constant volume over
    the unit cube, as Mitsuba's ``constvolume`` of identity ``to_world``)."""
    element = p.named(name, "volume")
    if element is None:
        value = p.color(name, default, emission=name == "radiance", unbounded=name == "sigma_t")
        return {"volume": "constant", "value": value} if name == "sigma_t" else value
    p.used_nested.add(id(element))
    v = Plugin(doc, element)
    matrix, _ = v.transform("to_world")
    if v.type == "constvolume":
        table = {"volume": "constant", "value": v.color("value", 1.0, unbounded=True)}
    else:
        if v.type != "gridvolume":
            doc.warn(element, f"volume type {v.type!r} is not supported")
        table = {"volume": "grid", "file": v.file("a gridvolume", "volume file")}
        if v.boolean("use_grid_bbox", False):
            table["use_grid_bbox"] = True
        for key, supported in (("filter_type", "bilinear"), ("wrap_mode", "clamp")):
            value = v.string(key, supported)
            if value != supported:
                doc.warn(element, f"'{key}' = {value!r} is not supported (wrt's volumes are {supported})")
        for key in HARMLESS_GRID:
            v.boolean(key, False)
    if not np.array_equal(matrix, np.eye(4)):
        table["transform"] = {"matrix": [x for row in matrix for x in as_list(row)]}
    v.finish()
    return table


def phase(doc: Document, element: Element) -> dict:
    """A medium's ``phase`` table: ``isotropic``, or ``hg`` with its ``g`` in (-1, 1)."""
    p = Plugin(doc, element)
    if p.type == "hg":
        table = {"type": "hg", "g": p.number("g", 0.8, above=-1.0, below=1.0)}
    else:
        if p.type != "isotropic":
            doc.warn(element, f"phase function {p.type!r} is not supported: converted as isotropic")
        table = {"type": "isotropic"}
    p.finish()
    return table
