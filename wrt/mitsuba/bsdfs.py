"""Converting Mitsuba's BSDFs into wrt materials: each ``<bsdf>`` once, named when a shape first
uses it, with the nearest wrt material (and a warning) for what wrt has no exact match for.
Mitsuba's one-sided BSDFs (``diffuse``, the conductors, the default BSDF) become materials with
``two_sided = false``, wrapped in ``twosided`` the same materials two-sided. A ``mask`` becomes a
wrt mask over its nested BSDF's material (named after the mask's, with ``_material``), a
``blendbsdf`` a wrt blend of its two nested BSDFs' (``_a`` and ``_b``)."""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

from ..conductors import METALS
from ..errors import token
from ..kernels.materials.principled import NUMBERS as PRINCIPLED_NUMBERS
from ..kernels.materials.principled import RATES as PRINCIPLED_RATES
from ..kernels.materials.principled import THIN_NUMBERS, THIN_RATES
from ..kernels.microfacet import DISTRIBUTIONS
from ..loader import NESTED_RULES
from .textures import texture, textured_color
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


@dataclass
class Material:
    """A converted BSDF: its wrt material parameters and whether Mitsuba shades both of its sides."""

    params: dict  # the [[material]] table but its name and two_sided (a mask's: but its material)
    two_sided: bool
    nested: tuple[Material, ...] = ()  # a mask's nested BSDF, a blend's two

    @property
    def table(self) -> dict:
        """The ``[[material]]`` table, without a name: ``two_sided = false`` for a one-sided BSDF."""
        return self.params if self.two_sided else {**self.params, "two_sided": False}

    def reflects(self) -> bool:
        colour = self.params.get("albedo", self.params.get("reflectance", [1.0]))
        if isinstance(colour, dict):  # a texture (wrt.mitsuba.textures)
            return True
        if self.params["type"] == "blend":
            return any(nested.reflects() for nested in self.nested)
        return self.params["type"] in (*TRANSMITTING, "plastic", "rough_plastic") or any(c > 0 for c in colour)


TRANSMITTING = ("dielectric", "rough_dielectric", "thin_dielectric")
DEFAULT_BSDF = Material({"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}, False)  # Mitsuba's (one-sided)
EMITTER_DEFAULT_BSDF = Material({"type": "diffuse", "albedo": [0.0, 0.0, 0.0]}, False)
"""Mitsuba's default BSDF of a shape that carries an emitter: black (its Shape gives an emitter a
diffuse BSDF of reflectance 0, not 0.5)."""


def ior(p: Plugin, name: str, default: str) -> float:
    """An index of refraction given as a number or as a name of ``IOR_TABLE``."""
    element = p.value(name, ("float", "string", "integer"))
    if element is None:
        return IOR_TABLE[default]
    text = p.doc.attr(element, "value")
    if element.tag != "string":
        return p.number(name, None)
    if text.strip().lower() not in IOR_TABLE:
        raise p.doc.error(element, f"'{name}' = {token(text)}: unknown IOR name (known: {', '.join(IOR_TABLE)})")
    return IOR_TABLE[text.strip().lower()]


def rough(p: Plugin, anisotropic: bool = True) -> dict:
    """The microfacet keys of a rough BSDF: ``distribution`` (Mitsuba's, beckmann by default) and
    ``roughness``, its alpha (``alpha``: a number or a texture, ``textured_number``), or where
    ``anisotropic`` (roughconductor, roughdielectric) and the BSDF gives ``alpha_u`` and
    ``alpha_v``, ``roughness`` and ``roughness_v``, each a number or a texture (Mitsuba's
    tangent is wrt's: dp/du made perpendicular to the shading normal)."""
    distribution = p.string("distribution", "beckmann").lower()
    if distribution not in DISTRIBUTIONS:
        raise p.doc.error(
            p.params["distribution"], f"distribution {token(distribution)} is not beckmann or ggx (Mitsuba rejects it)"
        )
    if anisotropic and (p.has("alpha_u") or p.has("alpha_v")):
        if not (p.has("alpha_u") and p.has("alpha_v")):
            raise p.doc.error(p.element, "give both alpha_u and alpha_v (Mitsuba rejects one alone)")
        if p.has("alpha"):
            raise p.doc.error(p.element, "give either alpha or alpha_u and alpha_v, not both (Mitsuba rejects it)")
        return {
            "roughness": textured_number(p, "alpha_u", 0.1),
            "roughness_v": textured_number(p, "alpha_v", 0.1),
            "distribution": distribution,
        }
    return {"roughness": textured_number(p, "alpha", 0.1), "distribution": distribution}


def conductor(p: Plugin, microfacets: dict) -> dict:
    """The ``[[material]]`` table of a conductor (``microfacets`` empty) or a rough conductor
    (``microfacets``: its ``rough`` keys), exact: a named ``material`` or ``eta`` and ``k`` become a
    wrt conductor; material "none" without them (Mitsuba's default: eta 0, k 1, F = 1) a mirror or a glossy material.
    ``specular_reflectance`` scales the Fresnel term (wrt's ``reflectance``)."""
    reflectance = textured_color(p, "specular_reflectance", 1.0)
    name = p.string("material", "none")
    if name != "none":
        if p.has("eta") or p.has("k"):
            raise p.doc.error(p.element, "give either eta and k or a material, not both (Mitsuba rejects it)")
        if name not in METALS:
            raise p.doc.error(p.element, f"unknown conductor material {token(name)} (known: none, {', '.join(METALS)})")
        table = {"type": "conductor", "metal": name}
    elif p.has("eta") or p.has("k"):
        table = {
            "type": "conductor",
            "eta": p.color("eta", 0.0, unbounded=True),
            "k": p.color("k", 1.0, unbounded=True),
        }
    else:
        table = {"type": "glossy" if microfacets else "mirror"}
    return {**table, **microfacets, "reflectance": reflectance}


def plastic(p: Plugin) -> dict:
    """The ``[[material]]`` table of a ``plastic`` or ``roughplastic``, exact:
    ``diffuse_reflectance`` is wrt's ``albedo``, ``specular_reflectance`` its ``reflectance``,
    ``int_ior`` its ``ior`` (over the scene's ``exterior_ior``, the ``ext_ior``), ``nonlinear`` the
    same."""
    interior = ior(p, "int_ior", "polypropylene")
    table = {
        "type": "plastic",
        "albedo": textured_color(p, "diffuse_reflectance", 0.5),
        "reflectance": textured_color(p, "specular_reflectance", 1.0),
        "ior": interior,
        "nonlinear": p.boolean("nonlinear", False),
    }
    if p.type == "roughplastic":
        if interior == ior(p, "ext_ior", "air"):
            raise p.doc.error(p.element, "int_ior and ext_ior must differ (Mitsuba rejects it)")
        p.boolean("sample_visible", True)  # how Mitsuba samples it: the noise, not the image
        table.update(type="rough_plastic", **rough(p, anisotropic=False))  # Mitsuba's roughplastic has one alpha
    return table


def principled_base(p: Plugin) -> dict:
    """The keys ``principled`` and ``principledthin`` share under other names: ``base_color`` is
    wrt's ``albedo``, ``anisotropic`` its ``anisotropy``; ``roughness`` the same."""
    return {
        "albedo": textured_color(p, "base_color", 0.5),
        "roughness": textured_number(p, "roughness", 0.5),
        "anisotropy": textured_number(p, "anisotropic", 0.0),
    }


def principled(p: Plugin) -> dict:
    """The ``[[material]]`` table of a ``principled``, exact: ``base_color`` is wrt's ``albedo``,
    ``anisotropic`` its ``anisotropy``, the other parameters the same (numbers or textures), ``eta``
    its ``ior``, or ``specular`` mapped to it as Mitsuba does (``2 / (1 - sqrt(0.08 specular)) - 1``,
    ``specular`` 0 taken as 0.001 where it transmits)."""
    table = {
        "type": "principled",
        **principled_base(p),
        **{key: textured_number(p, key, 0.0) for key in PRINCIPLED_NUMBERS},
        **{key: p.number(key, 1.0) for key in PRINCIPLED_RATES},
    }
    spec_trans = table["spec_trans"]
    transmits = isinstance(spec_trans, dict) or spec_trans != 0.0
    if p.has("eta") and p.has("specular"):
        raise p.doc.error(p.element, "give either eta or specular, not both (Mitsuba rejects it)")
    if p.has("eta"):
        table["ior"] = p.number("eta", 1.5)
    else:
        specular = p.number("specular", 0.5)
        if specular == 0.0 and transmits:
            specular = 1e-3
        table["ior"] = 2.0 / (1.0 - math.sqrt(0.08 * specular)) - 1.0
    return table


def principled_thin(p: Plugin) -> dict:
    """The ``[[material]]`` table of a ``principledthin``, exact: as ``principled``'s keys it has
    (``base_color`` is ``albedo``, ``anisotropic`` is ``anisotropy``), ``diff_trans`` (a number or a
    texture), its four sampling rates, and ``eta`` its ``ior`` (a number: a textured ``eta`` is
    refused)."""
    if p.named("eta", "texture") is not None:
        raise p.doc.error(p.element, "a textured eta of a principledthin is not supported (wrt's ior is a number)")
    return {
        "type": "principled_thin",
        **principled_base(p),
        **{key: textured_number(p, key, 0.0) for key in THIN_NUMBERS},
        "diff_trans": textured_number(p, "diff_trans", 0.0),
        "ior": p.number("eta", 1.5),
        **{key: p.number(key, 1.0) for key in THIN_RATES},
    }


def textured_number(p: Plugin, name: str, default: float) -> float | dict:
    """Number parameter ``name`` of ``p``: a number, or the texture table of its ``<texture>``,
    whose ``texture_float`` is Mitsuba's ``eval_1`` (a checkerboard's colours swapped: Mitsuba's
    checkerboard ``eval_1`` swaps them against its ``eval``)."""
    nested = p.named(name, "texture")
    if nested is None or name in p.params:
        return p.number(name, default)
    p.used.add(name)
    p.used_nested.add(id(nested))
    table = texture(p.doc, nested)
    if table["texture"] == "checkerboard":
        table.update(color0=table["color1"], color1=table["color0"])
    if table["texture"] == "constant" and isinstance(table["value"], list):
        raise p.doc.error(nested, f"'{name}': a rawconstant of a colour has no eval_1 (Mitsuba rejects it)")
    return table


def mask_opacity(p: Plugin) -> float | dict:
    """A mask's ``opacity``: a number clamped to [0, 1] as Mitsuba does, or a texture
    (``textured_number``)."""
    opacity = textured_number(p, "opacity", 0.5)
    return opacity if isinstance(opacity, dict) else min(max(opacity, 0.0), 1.0)


class Materials:
    """The ``[[material]]`` tables of the converted scene, and the dielectrics' exterior iors."""

    def __init__(self, doc: Document):
        self.doc = doc
        self.tables: list[dict] = []
        self.sources: list[Element | None] = []  # the element each table came from
        self.converted: dict[int, Material] = {}  # by id of the <bsdf> element
        self.names: dict[int, str] = {}  # names of those that shapes use
        self.ext_iors: list[tuple[float, Element]] = []

    def of(self, element: Element | None, emitter: bool = False) -> Material:
        """A BSDF element converted once, however often it is referenced (None: Mitsuba's default
        BSDF, of a shape with an ``emitter`` or not)."""
        if element is None:
            return EMITTER_DEFAULT_BSDF if emitter else DEFAULT_BSDF
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
            table = material.table
            if material.params["type"] == "mask":
                table = {**table, "material": self.add(f"{base}_material", material.nested[0].table, element)}
            elif material.params["type"] == "blend":
                names = [self.add(f"{base}_{k}", nested.table, element) for k, nested in zip("ab", material.nested)]
                table = {**table, "materials": names}
            self.names[id(element)] = self.add(base, table, element)
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
            if front.params["type"] in (*TRANSMITTING, "mask"):
                raise self.doc.error(inner[0], "a twosided BSDF cannot nest a BSDF that transmits (Mitsuba rejects it)")
            if front.params["type"] in ("principled", "principled_thin"):
                self.doc.warn(
                    element, "a twosided principled is not supported: its back side stays Mitsuba's one-sided"
                )
            return Material(front.params, True, tuple(Material(n.params, True, n.nested) for n in front.nested))
        if p.type == "diffuse":
            material = Material({"type": "diffuse", "albedo": textured_color(p, "reflectance", 0.5)}, False)
        elif p.type in ("conductor", "roughconductor"):
            material = Material(conductor(p, rough(p) if p.type == "roughconductor" else {}), False)
        elif p.type in ("dielectric", "roughdielectric"):
            interior, exterior = ior(p, "int_ior", "bk7"), ior(p, "ext_ior", "air")
            for name in ("specular_reflectance", "specular_transmittance"):
                if p.color(name, 1.0) != [1.0, 1.0, 1.0]:
                    self.doc.warn(p.params[name], f"'{name}' (a non-physical scale) is not supported: ignored")
            self.ext_iors.append((exterior, element))
            table = {"type": "dielectric", "ior": interior}
            if p.type == "roughdielectric":
                if interior == exterior:
                    raise self.doc.error(element, "int_ior and ext_ior must differ (Mitsuba rejects it)")
                p.boolean("sample_visible", True)  # how Mitsuba samples it: the noise, not the image
                table = {"type": "rough_dielectric", "ior": interior, **rough(p)}
            material = Material(table, True)
        elif p.type in ("plastic", "roughplastic"):
            material = Material(plastic(p), False)
            self.ext_iors.append((ior(p, "ext_ior", "air"), element))
        elif p.type == "thindielectric":
            self.ext_iors.append((ior(p, "ext_ior", "air"), element))
            material = Material(
                {
                    "type": "thin_dielectric",
                    "ior": ior(p, "int_ior", "bk7"),
                    "reflectance": textured_color(p, "specular_reflectance", 1.0),
                    "transmittance": textured_color(p, "specular_transmittance", 1.0),
                },
                True,
            )
        elif p.type == "principled":
            material = Material(principled(p), True)  # its sides are its own (the kernel's front)
        elif p.type == "principledthin":
            material = Material(principled_thin(p), True)  # the same from both sides
        elif p.type == "null":
            material = Material({"type": "null"}, True)
        elif p.type == "mask":
            return self._mask(p)
        elif p.type == "blendbsdf":
            return self._blend(p)
        elif p.type == "normalmap":
            return self._normal_map(p)
        elif p.type == "bumpmap":
            return self._bump_map(p)
        else:
            return self._closest(p)
        p.finish()
        return material

    def _mask(self, p: Plugin) -> Material:
        """A ``mask``, exact: its ``opacity`` (``mask_opacity``) over its nested BSDF, which is no
        mask nor a dielectric (a medium's boundary in wrt)."""
        nested = p.children("bsdf")
        if not nested:
            raise self.doc.error(p.element, "a mask BSDF needs a nested <bsdf>")
        opacity = mask_opacity(p)
        p.finish()
        inner = self._convert(nested[0])
        if inner.params["type"] in ("mask", "dielectric", "rough_dielectric"):
            self.doc.warn(p.element, f"a mask over a {inner.params['type']} is not supported: the mask is left out")
            return inner
        return Material({"type": "mask", "opacity": opacity}, True, (inner,))

    def _blend(self, p: Plugin) -> Material:
        """A ``blendbsdf``, exact: its ``weight`` (a number clamped to [0, 1], or a texture's
        ``eval_1``, clamped in the kernels) between its two nested BSDFs, neither of which is a
        mask, a blend, null or a dielectric (a medium's boundary in wrt)."""
        nested = p.children("bsdf")
        if len(nested) != 2:
            raise self.doc.error(p.element, "a blendbsdf needs exactly two nested <bsdf>s (Mitsuba rejects it)")
        weight = textured_number(p, "weight", 0.5)
        p.finish()
        materials = tuple(self._convert(element) for element in nested)
        for element, material in zip(nested, materials):
            if material.params["type"] in NESTED_RULES["blend"][1]:  # the loader's rule, located here
                raise self.doc.error(element, f"a blendbsdf of a {material.params['type']} is not supported")
        weight = weight if isinstance(weight, dict) else min(max(weight, 0.0), 1.0)
        return Material({"type": "blend", "weight": weight}, True, materials)

    def _normal_map(self, p: Plugin) -> Material:
        """``normalmap``: the nested BSDF's material with the ``normalmap`` bitmap (or constant:
        a ``rawconstant`` texture, an ``<rgb>`` or ``<spectrum>``) as its ``normal_map``, exact:
        the shading frame perturbed (wrt's ``perturbed_normal``, mirrored about the unperturbed
        normal where the ray sees the mapped surface from below) and the
        BSDF scaled by Mitsuba's shadowing function (``normal_map_shadowing``). A map Mitsuba
        would sRGB-decode, or the shadowing function turned off, is an approximation."""
        nested = p.children("bsdf")
        if len(nested) != 1:
            raise self.doc.error(p.element, "a normalmap BSDF needs exactly one nested <bsdf> (Mitsuba rejects it)")
        element = p.named("normalmap", "texture")
        if element is not None:
            p.used_nested.add(id(element))
            table = texture(self.doc, element)
        elif p.has("normalmap"):  # a constant (<rgb>, <spectrum>): its value in the RGB variants, as given
            element = p.params["normalmap"]
            table = {"texture": "constant", "value": p.color("normalmap", 0.5)}
        else:
            raise self.doc.error(p.element, 'a normalmap BSDF needs a <texture name="normalmap">')
        if table["texture"] == "checkerboard":
            raise self.doc.error(element, "a normal map must be a bitmap or a constant texture in wrt")
        if table["texture"] == "bitmap" and not table.pop("raw", False):
            self.doc.warn(element, "a normal map without raw = true (sRGB-decoded) is not supported: read raw")
        inner = self._shadowed_inner(p, nested[0], "normal map")
        return Material({**inner.params, "normal_map": table}, inner.two_sided, inner.nested)

    def _shadowed_inner(self, p: Plugin, element, what: str) -> Material:
        """The nested BSDF ``element`` of a normal or bump map ``p`` (``what``), converted after
        ``p``'s keys: its shadowing function is always on (turned off: a warning)."""
        if not p.boolean("use_shadowing_function", True):
            self.doc.warn(
                p.params["use_shadowing_function"],
                f"a {what} without its shadowing function is not supported: converted with it",
            )
        p.finish()
        return self._convert(element)

    def _bump_map(self, p: Plugin) -> Material:
        """``bumpmap``: the nested BSDF's material with its height texture (a bitmap, of any name)
        as its ``bump_map`` and ``scale`` as its ``bump_scale``, exact: the shading frame of the
        height field's gradient (wrt's ``bumped_normal``), mirrored and shadowed as a normal map's.
        The shadowing function turned off is an approximation, and so is a bump map over an
        anisotropic BSDF: Mitsuba 3.9 makes its tangent of the surface's dp/du in world space and
        the tilted normal in the shading frame's coordinates, wrt of both in world space (the
        tangent plane's; measured on examples/mitsuba/bumpmap.xml's sphere made anisotropic: means
        +1.8%). A bump map over a normal- or bump-mapped BSDF is refused."""
        nested = p.children("bsdf")
        textures = [child for _, child in p.nested if child.tag == "texture"]
        if len(nested) != 1 or len(textures) != 1:
            raise self.doc.error(p.element, "a bumpmap BSDF needs one nested <bsdf> and one <texture> (Mitsuba's)")
        p.used_nested.add(id(textures[0]))
        table = texture(self.doc, textures[0])
        if table["texture"] != "bitmap":
            raise self.doc.error(textures[0], "a bump map must be a bitmap texture in wrt (a height field's gradient)")
        scale = p.number("scale", 1.0)
        inner = self._shadowed_inner(p, nested[0], "bump map")
        if "normal_map" in inner.params or "bump_map" in inner.params:
            raise self.doc.error(p.element, "a bumpmap over a normal- or bump-mapped BSDF is not supported")
        if any("roughness_v" in m.params for m in (inner, *inner.nested)):
            self.doc.warn(
                p.element,
                "a bumpmap over an anisotropic BSDF: its tangent is the bumped surface's, not Mitsuba 3.9's"
                " (which mixes world and shading-frame coordinates)",
            )
        return Material({**inner.params, "bump_map": table, "bump_scale": scale}, inner.two_sided, inner.nested)

    def _closest(self, p: Plugin) -> Material:
        """An unsupported BSDF: its nearest wrt material, with a warning saying which."""
        self.doc.warn(p.element, "not supported: converted as diffuse 0.5 (Mitsuba's default BSDF)")
        return Material({"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}, False)
