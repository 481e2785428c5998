"""Converting Mitsuba's BSDFs into wrt materials: each ``<bsdf>`` once, named when a shape first
uses it, with the nearest wrt material (and a warning) for what wrt has no exact match for.
Mitsuba's one-sided BSDFs (``diffuse``, the conductors, the default BSDF) become materials with
``two_sided = false``, wrapped in ``twosided`` the same materials two-sided."""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np

from .transforms import as_list
from .xml import Document, Element, Plugin

IOR_TABLE = {
    "vacuum": 1.0,
    "helium": 1.000036,
    "hydrogen": 1.000132,
    "air": 1.000277,
    "carbon dioxide": 1.00045,
    "water": 1.3330,
    "acetone": 1.36,
    "ethanol": 1.361,
    "carbon tetrachloride": 1.461,
    "glycerol": 1.4729,
    "benzene": 1.501,
    "silicone oil": 1.52045,
    "bromine": 1.661,
    "water ice": 1.31,
    "fused quartz": 1.458,
    "pyrex": 1.470,
    "acrylic glass": 1.49,
    "polypropylene": 1.49,
    "bk7": 1.5046,
    "sodium chloride": 1.544,
    "amber": 1.55,
    "pet": 1.5750,
    "diamond": 2.419,
}
"""Mitsuba 3's named indices of refraction (``int_ior``/``ext_ior`` strings, case-insensitive;
Hecht, Optics, 4th ed., ~589 nm)."""

CONDUCTOR_F0 = {
    "Ag": (0.9748, 0.9575, 0.9063),
    "Al": (0.9280, 0.9178, 0.9189),
    "AlAs": (0.3200, 0.2783, 0.1430),
    "Au": (0.9667, 0.8020, 0.3241),
    "Be": (0.5975, 0.5206, 0.5062),
    "Cr": (0.6876, 0.6491, 0.6870),
    "CsI": (0.1325, 0.0675, 0.0619),
    "Cu": (0.9520, 0.6198, 0.5106),
    "Cu2O": (0.3147, 0.2455, 0.2379),
    "CuO": (0.2907, 0.1982, 0.1834),
    "Hg": (0.8140, 0.7702, 0.7631),
    "HgTe": (0.4699, 0.3665, 0.3507),
    "Ir": (0.7426, 0.6802, 0.6308),
    "K": (0.9539, 0.9363, 0.9201),
    "Li": (0.9248, 0.8844, 0.7933),
    "MgO": (0.1244, 0.0603, 0.0526),
    "Mo": (0.6182, 0.5618, 0.5409),
    "Na_palik": (0.9785, 0.9597, 0.9315),
    "Nb": (0.5640, 0.4895, 0.4731),
    "Ni_palik": (0.7001, 0.5942, 0.4936),
    "Rh": (0.8243, 0.7544, 0.7216),
    "Se": (0.3793, 0.2507, 0.2413),
    "SiC": (0.2711, 0.1873, 0.1808),
    "SnTe": (0.4070, 0.1084, 0.0152),
    "Ta": (0.4565, 0.3419, 0.3799),
    "Te": (0.6350, 0.5781, 0.5617),
    "ThF4": (0.0861, 0.0328, 0.0264),
    "TiC": (0.5482, 0.4397, 0.4116),
    "TiN": (0.6409, 0.4523, 0.1976),
    "TiO2": (0.3039, 0.2246, 0.2380),
    "VC": (0.5297, 0.4179, 0.3798),
    "VN": (0.5251, 0.3926, 0.3106),
    "V_palik": (0.5727, 0.5107, 0.5365),
    "W": (0.5746, 0.4778, 0.4331),
    "a-C": (0.2794, 0.1940, 0.1691),
    "d-C": (0.2123, 0.1579, 0.1449),
}
"""Normal-incidence reflectance (linear RGB) of Mitsuba 3's named conductors, measured with
Mitsuba 3.9 ``scalar_rgb`` (a ``conductor`` sampled at normal incidence). A ``<name>_palik``
material not listed has the same value as ``<name>``. wrt's mirror and glossy materials have a
constant Fresnel factor, so a named conductor converts to this value with a warning."""


@dataclass
class Material:
    """A converted BSDF: its wrt material parameters and whether Mitsuba shades both of its sides."""

    params: dict  # the [[material]] table but its name and two_sided
    two_sided: bool

    @property
    def table(self) -> dict:
        """The ``[[material]]`` table, without a name: ``two_sided = false`` for a one-sided BSDF."""
        return self.params if self.two_sided else {**self.params, "two_sided": False}

    def reflects(self) -> bool:
        colour = self.params.get("albedo", self.params.get("reflectance", [1.0]))
        return self.params["type"] == "dielectric" or any(c > 0 for c in colour)


DEFAULT_BSDF = Material({"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}, False)  # Mitsuba's (one-sided)


def ior(p: Plugin, name: str, default: str) -> float:
    """An index of refraction given as a number or as a name of ``IOR_TABLE``."""
    element = p.value(name, ("float", "string", "integer"))
    if element is None:
        return IOR_TABLE[default]
    text = p.doc.attr(element, "value")
    if element.tag != "string":
        return p.number(name, None)
    if text.strip().lower() not in IOR_TABLE:
        raise p.doc.error(element, f"'{name}' = {text!r}: unknown IOR name (known: {', '.join(IOR_TABLE)})")
    return IOR_TABLE[text.strip().lower()]


def alpha(p: Plugin) -> float:
    """The GGX alpha of a rough BSDF (isotropic: the geometric mean of an anisotropic pair)."""
    distribution = p.string("distribution", "beckmann")
    if distribution != "ggx":
        p.doc.warn(
            p.params.get("distribution", p.element),
            f"distribution '{distribution}' is converted as GGX with the same alpha",
        )
    if p.has("alpha_u") or p.has("alpha_v"):
        alpha_u, alpha_v = p.number("alpha_u", 0.1), p.number("alpha_v", 0.1)
        if alpha_u != alpha_v:
            p.doc.warn(
                p.element,
                f"anisotropic roughness is not supported: alpha = {math.sqrt(alpha_u * alpha_v):.4g} (geometric mean)",
            )
        return math.sqrt(alpha_u * alpha_v)
    return p.number("alpha", 0.1)


def conductor_reflectance(p: Plugin) -> list[float]:
    """Reflectance of a (rough) conductor: exact for material "none" (Mitsuba's default, F = 1),
    the normal-incidence Fresnel reflectance otherwise (with a warning)."""
    scale = p.color("specular_reflectance", 1.0)
    if p.has("eta") or p.has("k"):
        eta = np.array(p.color("eta", 0.0, unbounded=True))
        k = np.array(p.color("k", 1.0, unbounded=True))
        f0 = ((eta - 1) ** 2 + k**2) / ((eta + 1) ** 2 + k**2)
        source = "eta, k"
    else:
        name = p.string("material", "none")
        if name == "none":
            return scale
        known = CONDUCTOR_F0.get(name, CONDUCTOR_F0.get(name.removesuffix("_palik")))
        if known is None:
            known = ", ".join(["none", *CONDUCTOR_F0])
            raise p.doc.error(p.element, f"unknown conductor material {name!r} (known: {known}, and <name>_palik)")
        f0, source = np.array(known), f"material '{name}'"
    reflectance = as_list(np.clip(f0 * scale, 0.0, 1.0))
    p.doc.warn(
        p.element,
        f"{source}: angle-dependent Fresnel approximated by its normal-incidence value "
        f"{[round(c, 4) for c in reflectance]}",
    )
    return reflectance


class Materials:
    """The ``[[material]]`` tables of the converted scene, and the dielectrics' exterior iors."""

    def __init__(self, doc: Document):
        self.doc = doc
        self.tables: list[dict] = []
        self.sources: list[Element | None] = []  # the element each table came from
        self.converted: dict[int, Material] = {}  # by id of the <bsdf> element
        self.names: dict[int, str] = {}  # names of those that shapes use
        self.ext_iors: list[tuple[float, Element]] = []

    def of(self, element: Element | None) -> Material:
        """A BSDF element converted once, however often it is referenced (None: Mitsuba's default BSDF)."""
        if element is None:
            return DEFAULT_BSDF
        if id(element) not in self.converted:
            self.converted[id(element)] = self._convert(element)
        return self.converted[id(element)]

    def name(self, element: Element | None) -> str:
        """The name of a BSDF's wrt material (None: Mitsuba's default BSDF), added to
        ``[[material]]`` when first used."""
        if id(element) not in self.names:
            material = self.of(element)
            base = "default_bsdf"
            if element is not None:
                base = element.attrs.get("id") or f"{material.params['type']}@{element.line}"
            self.names[id(element)] = self.add(base, material.table, element)
        return self.names[id(element)]

    def add(self, base: str, table: dict, source: Element | None) -> str:
        """Add a material table, converted from ``source``, under a name made unique from
        ``base``; returns the name."""
        names = {m["name"] for m in self.tables}
        name, n = base, 2
        while name in names or name == "default":
            name, n = f"{base}_{n}", n + 1
        self.tables.append({"name": name, **table})
        self.sources.append(source)
        return name

    def exterior_ior(self) -> float:
        """[render] exterior_ior: the ext_ior of the dielectrics (the most common one, with a
        warning for those that differ; wrt takes a nested dielectric's outside from its nesting)."""
        if not self.ext_iors:
            return 1.0
        chosen = Counter(v for v, _ in self.ext_iors).most_common(1)[0][0]
        for value, element in self.ext_iors:
            if value != chosen:
                self.doc.warn(
                    element,
                    f"ext_ior {value:g} differs from the scene's exterior_ior {chosen:g}: wrt takes the medium "
                    "outside a dielectric from the dielectric enclosing it, or [render] exterior_ior",
                )
        return chosen

    def _convert(self, element: Element) -> Material:
        if element.tag != "bsdf":
            raise self.doc.error(element, "is not a <bsdf>")
        p = Plugin(self.doc, element)
        if p.type == "twosided":
            inner = p.children("bsdf")
            if not inner:
                raise self.doc.error(element, "a twosided BSDF needs a nested <bsdf>")
            if len(inner) > 1 and inner[1] is not inner[0]:
                self.doc.warn(inner[1], "a different BSDF on the back side is not supported: both sides use the first")
            p.finish()
            front = self._convert(inner[0])
            if front.params["type"] == "dielectric":
                raise self.doc.error(inner[0], "a twosided BSDF cannot nest a BSDF that transmits (Mitsuba rejects it)")
            return Material(front.params, True)
        if p.type == "diffuse":
            material = Material({"type": "diffuse", "albedo": p.color("reflectance", 0.5)}, False)
        elif p.type == "conductor":
            material = Material({"type": "mirror", "reflectance": conductor_reflectance(p)}, False)
        elif p.type == "roughconductor":
            roughness = alpha(p)
            material = Material(
                {"type": "glossy", "roughness": roughness, "reflectance": conductor_reflectance(p)}, False
            )
        elif p.type == "dielectric":
            interior, exterior = ior(p, "int_ior", "bk7"), ior(p, "ext_ior", "air")
            for name in ("specular_reflectance", "specular_transmittance"):
                if p.color(name, 1.0) != [1.0, 1.0, 1.0]:
                    self.doc.warn(p.params[name], f"'{name}' (a non-physical scale) is not supported: ignored")
            self.ext_iors.append((exterior, element))
            material = Material({"type": "dielectric", "ior": interior}, True)
        else:
            return self._closest(p)
        p.finish()
        return material

    def _closest(self, p: Plugin) -> Material:
        """An unsupported BSDF: its nearest wrt material, with a warning saying which."""
        nested = p.children("bsdf")
        if p.type in ("bumpmap", "normalmap", "mask") and nested:
            self.doc.warn(p.element, "not supported: the nested BSDF is used without it")
            return self._convert(nested[0])
        if p.type in ("plastic", "roughplastic", "principled"):
            albedo = p.color("base_color" if p.type == "principled" else "diffuse_reflectance", 0.5)
            self.doc.warn(p.element, f"not supported: converted as diffuse, albedo {albedo}")
            return Material({"type": "diffuse", "albedo": albedo}, False)
        if p.type == "roughdielectric":
            self.doc.warn(p.element, "roughness is not supported: converted as a smooth dielectric")
            self.ext_iors.append((ior(p, "ext_ior", "air"), p.element))
            return Material({"type": "dielectric", "ior": ior(p, "int_ior", "bk7")}, True)
        self.doc.warn(p.element, "not supported: converted as diffuse 0.5 (Mitsuba's default BSDF)")
        return Material({"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}, False)
