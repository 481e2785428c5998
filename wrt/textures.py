"""Textures on the host: reading a texture's scene table, its bitmap file, and packing a scene's
textures into the flat arrays of ``wrt.kernels.textures.TextureData``.

A texture gives a material parameter (``SLOTS``: ``albedo``, ``specular``, ``reflectance``,
``roughness``, ...) a value that varies with the surface's (u, v) coordinates
(``wrt.kernels.traverse.texture_context``). Three kinds, as Mitsuba 3's plugins: ``Constant`` (one
value everywhere, Mitsuba's ``rawconstant``: what a constant normal map is; on the device a
checkerboard of two equal colours), ``Checkerboard`` (two colours in squares of side 1/2 in uv)
and ``Bitmap`` (an image file read
with OpenImageIO: 8- and 16-bit integer files are sRGB-encoded and decoded to linear unless
``raw``, floating-point files (OpenEXR, Radiance HDR) are linear; a grey image is grey in all
three channels, an alpha channel is ignored). These map uv through ``to_uv`` first, a 2D affine
transform (3x3, acting on ``(u, v, 1)``). A fourth, ``MeshAttribute`` (Mitsuba's
``mesh_attribute``), takes a mesh's vertex or face values instead of uv. The scene format is in
docs/scene-format.md.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from wrt.kernels.textures import (
    BILINEAR,
    BITMAP,
    CHECKERBOARD,
    CLAMP,
    MESH_ATTRIBUTE,
    MIRROR,
    NEAREST,
    REPEAT,
    SLOTS,
)

from .imageio import oiio, read_pixels, srgb_decode

FILTERS = {"bilinear": BILINEAR, "nearest": NEAREST}
WRAPS = {"repeat": REPEAT, "mirror": MIRROR, "clamp": CLAMP}
KINDS = ("constant", "checkerboard", "bitmap", "mesh_attribute")
ATTRIBUTE_PREFIXES = ("vertex_", "face_")  # a mesh attribute's name starts with one of them (Mitsuba 3's rule)
MAX_TEXELS = 1 << 26  # texels of one bitmap (64 Mi: 768 MiB of float32 RGB on the device)
LUMINANCE = np.array([0.212671, 0.715160, 0.072169])  # Mitsuba 3's (Rec. 709) weights: a bitmap's texture_float


class TextureFileError(ValueError):
    """A bitmap file wrt cannot use; the message says why."""


@dataclass(frozen=True, eq=False)
class Constant:
    """Mitsuba 3's ``rawconstant``: ``value`` (linear RGB, not decoded) at every uv."""

    value: tuple[float, float, float]
    to_uv: np.ndarray = field(default_factory=lambda: np.eye(3))

    def values(self) -> np.ndarray:
        """Its one value (1, 3)."""
        return np.array([self.value], dtype=np.float64)

    def numbers(self) -> np.ndarray:
        """Its ``texture_float`` (1,): the channels' mean, as a checkerboard's (its device form)."""
        return self.values().mean(axis=1)


@dataclass(frozen=True, eq=False)
class Checkerboard:
    """Mitsuba 3's ``checkerboard``: ``color0`` (linear RGB) where the fractional parts of the
    (transformed) u and v are both above 1/2 or both not, ``color1`` elsewhere."""

    color0: tuple[float, float, float] = (0.4, 0.4, 0.4)
    color1: tuple[float, float, float] = (0.2, 0.2, 0.2)
    to_uv: np.ndarray = field(default_factory=lambda: np.eye(3))

    def values(self) -> np.ndarray:
        """Every value the texture takes (2, 3), linear RGB."""
        return np.array([self.color0, self.color1], dtype=np.float64)

    def numbers(self) -> np.ndarray:
        """Every value of ``wrt.kernels.textures.texture_float`` (2,): the colours' channel means."""
        return self.values().mean(axis=1)


@dataclass(frozen=True, eq=False)
class Bitmap:
    """Mitsuba 3's ``bitmap``: the image of ``file`` as ``texels`` (H, W, 3) float32 linear RGB, row
    0 the top row (uv (0, 0) is the top left corner), looked up with ``filter`` (bilinear,
    nearest) and ``wrap`` (repeat, mirror, clamp) outside [0, 1]^2."""

    file: str
    texels: np.ndarray = field(repr=False)
    filter: str = "bilinear"
    wrap: str = "repeat"
    raw: bool = False
    to_uv: np.ndarray = field(default_factory=lambda: np.eye(3))

    def values(self) -> np.ndarray:
        """Every value the texture takes (H * W, 3), linear RGB (a bilinear lookup stays within them)."""
        return self.texels.reshape(-1, 3).astype(np.float64)

    def numbers(self) -> np.ndarray:
        """Every value of ``wrt.kernels.textures.texture_float`` (H * W,): the texels' luminance."""
        return self.values() @ LUMINANCE


@dataclass(frozen=True, eq=False)
class MeshAttribute:
    """Mitsuba 3's ``mesh_attribute``: attribute ``name`` of the mesh it is on (``wrt.scene.Mesh.
    attributes``; ``vertex_...`` interpolated over each triangle by its barycentric coordinates,
    ``face_...`` constant over each face) times ``scale``. Its values are the meshes', known once
    they are read (``wrt.loader``); uv and ``to_uv`` play no part."""

    name: str
    scale: float = 1.0
    to_uv: np.ndarray = field(default_factory=lambda: np.eye(3))


Texture = Constant | Checkerboard | Bitmap | MeshAttribute


def attribute_names(materials) -> tuple[str, ...]:
    """The mesh attributes the textures of ``materials`` read, sorted: the order of their corner
    values on the device (``wrt.geometry.Primitives.tri_attributes``)."""
    return tuple(sorted({t.name for m in materials for _, t in m.textures if isinstance(t, MeshAttribute)}))


def mean_value(texture: Texture) -> tuple[float, float, float]:
    """The texture's mean colour over its values: what a constant stands for (the raycast colour)."""
    return tuple(float(c) for c in texture.values().mean(axis=0))


def read_bitmap(path: str, *, raw: bool = False) -> np.ndarray:
    """The texels (H, W, 3) float32 linear RGB of an image file, row 0 at the top: integer
    formats sRGB-decoded unless ``raw``, floating-point ones as they are; 1 or 2 channels (grey,
    grey and alpha) spread to RGB, an alpha channel dropped. Raises ``TextureFileError``, whose
    message says why without the path (the loader names the file): the file is missing, not a
    regular file or too large in pixels (``wrt.imageio.read_pixels``, before a pixel is read), or
    not an image OpenImageIO reads."""
    if not os.path.lexists(path):
        raise TextureFileError("no such file")
    try:
        spec, pixels = read_pixels(path, "texture", error=TextureFileError, max_pixels=MAX_TEXELS)
    except TextureFileError as e:
        raise TextureFileError(str(e).removeprefix(f"{path}: ")) from None
    pixels = pixels.astype(np.float64)
    if spec.nchannels in (1, 2):
        rgb = np.repeat(pixels[..., :1], 3, axis=2)
    elif spec.nchannels in (3, 4):
        rgb = pixels[..., :3]
    else:
        raise TextureFileError(f"has {spec.nchannels} channels (1 to 4 are read: grey or RGB, and alpha)")
    if not np.all(np.isfinite(rgb)):
        raise TextureFileError("has NaN or infinite texels")
    if spec.format.basetype not in (oiio.FLOAT, oiio.HALF, oiio.DOUBLE) and not raw:
        rgb = srgb_decode(rgb)
    return rgb.astype(np.float32)


def read_texture(t, scene_dir: str) -> Texture:
    """The texture of an inline table ``t`` (a ``wrt.loader._Table``): ``texture`` (its kind) and
    the keys of that kind (docs/scene-format.md). Its checks raise ``t.error``."""
    kind = t.string("texture", choices=KINDS)
    to_uv = np.eye(3) if kind == "mesh_attribute" else _to_uv(t)  # a mesh attribute's scale scales its values
    if kind == "constant":
        value = t.get("value", None)
        grey = isinstance(value, (int, float)) and not isinstance(value, bool)
        texture = Constant(value=(t.number("value"),) * 3 if grey else t.vec3("value"), to_uv=to_uv)
    elif kind == "mesh_attribute":
        if "to_uv" in t.data:
            raise t.error("to_uv", "does not apply to a mesh attribute (it is not looked up by uv)", t.data["to_uv"])
        name = t.string("name")
        if not name.startswith(ATTRIBUTE_PREFIXES) or name in ATTRIBUTE_PREFIXES:
            raise t.error("name", "must start with vertex_ or face_ (a vertex or a face attribute)", name)
        texture = MeshAttribute(name=name, scale=t.number("scale", 1.0, lo=-1e18, hi=1e18))
    elif kind == "checkerboard":
        texture = Checkerboard(
            color0=t.vec3("color0", Checkerboard.color0), color1=t.vec3("color1", Checkerboard.color1), to_uv=to_uv
        )
    else:
        name = t.string("file")
        raw = t.boolean("raw", False)
        try:
            texels = read_bitmap(os.path.join(scene_dir, name), raw=raw)
        except TextureFileError as e:
            raise t.error("file", str(e), name) from None
        texture = Bitmap(
            file=os.path.join(scene_dir, name),
            texels=texels,
            filter=t.string("filter", "bilinear", choices=FILTERS),
            wrap=t.string("wrap", "repeat", choices=WRAPS),
            raw=raw,
            to_uv=to_uv,
        )
    t.finish()
    return texture


def _to_uv(t) -> np.ndarray:
    """``to_uv`` of a texture table: ``scale`` (one number, or ``[su, sv]``) or ``to_uv`` (6
    numbers ``[a, b, c, d, e, f]``: ``u' = a u + b v + c``, ``v' = d u + e v + f``), identity when
    neither is given; as a 3x3 matrix acting on ``(u, v, 1)``."""
    if "scale" in t.data and "to_uv" in t.data:
        raise t.error("scale", "is given with 'to_uv': give one of them", t.data["scale"])
    matrix = np.eye(3)
    if "scale" in t.data:
        scale = t.get("scale", None)
        numbers = scale if isinstance(scale, list) else [scale, scale]
        if len(numbers) != 2 or not all(_finite_number(x) for x in numbers):
            raise t.error("scale", "must be a finite number or 2 finite numbers [su, sv]", scale)
        matrix[0, 0], matrix[1, 1] = numbers
    elif "to_uv" in t.data:
        numbers = t.get("to_uv", None)
        if not isinstance(numbers, list) or len(numbers) != 6 or not all(_finite_number(x) for x in numbers):
            raise t.error("to_uv", "must be 6 finite numbers [a, b, c, d, e, f]", numbers)
        matrix[:2] = np.reshape(numbers, (2, 3))
    if not np.all(np.abs(matrix) <= 1e18):
        raise t.error(
            "to_uv" if "to_uv" in t.data else "scale", "must be at most 1e18 in magnitude", t.data.get("to_uv")
        )
    return matrix


def _finite_number(x) -> bool:
    return not isinstance(x, bool) and isinstance(x, (int, float)) and math.isfinite(x)


@dataclass
class TextureTable:
    """A scene's textures packed as ``TextureData`` holds them (numpy, ready for upload)."""

    slot: np.ndarray  # (materials, len(SLOTS)) int32: texture index, -1 for the constant
    kind: np.ndarray  # (N,) int32
    to_uv: np.ndarray  # (N, 3, 3) float32
    color0: np.ndarray  # (N, 3) float32
    color1: np.ndarray
    offset: np.ndarray  # (N,) int32
    width: np.ndarray
    height: np.ndarray
    filter: np.ndarray
    wrap: np.ndarray
    texels: np.ndarray  # (texels, 3) float32; one black texel when there is no bitmap


def texture_table(materials) -> TextureTable:
    """The textures of ``materials`` (``wrt.scene.Material``s, in device order), each texture object
    once however many parameters share it (a mesh attribute's corner values are the geometry's:
    ``TextureData.corners``, uploaded by ``wrt.device``)."""
    index: dict[int, int] = {}
    textures: list[Texture] = []
    slot = np.full((max(len(materials), 1), len(SLOTS)), -1, dtype=np.int32)
    for m, material in enumerate(materials):
        for name, texture in material.textures:
            if id(texture) not in index:
                index[id(texture)] = len(textures)
                textures.append(texture)
            slot[m, SLOTS.index(name)] = index[id(texture)]
        if material.roughness_v is None:  # isotropic: alpha_v is alpha_u, its texture too (one lookup)
            slot[m, SLOTS.index("roughness_v")] = slot[m, SLOTS.index("roughness")]
    return _pack(textures, slot, attribute_names(materials))


def light_texture_table(textures: list[Texture]) -> TextureTable:
    """The lights' own table of ``textures`` (in the order of their ``LightData.texture`` indices;
    ``slot`` a placeholder row: lights have no slots)."""
    return _pack(textures, np.full((1, len(SLOTS)), -1, dtype=np.int32))


def _pack(textures: list[Texture], slot: np.ndarray, attributes: tuple[str, ...] = ()) -> TextureTable:
    """``textures`` (their index their position) in ``TextureData``'s flat arrays; a mesh
    attribute's ``offset`` its place in ``attributes``, ``width`` their count, ``color0`` its scale."""
    bitmaps = [t.texels for t in textures if isinstance(t, Bitmap)]
    sizes = [b.shape[0] * b.shape[1] for b in bitmaps]
    offsets = iter(np.cumsum([0, *sizes[:-1]]))
    rows = []
    for t in textures:
        if isinstance(t, Bitmap):
            h, w = t.texels.shape[:2]
            rows.append((BITMAP, (0.0,) * 3, (0.0,) * 3, next(offsets), w, h, FILTERS[t.filter], WRAPS[t.wrap]))
        elif isinstance(t, MeshAttribute):
            scale = (t.scale,) * 3
            rows.append((MESH_ATTRIBUTE, scale, scale, attributes.index(t.name), len(attributes), 0, NEAREST, REPEAT))
        else:
            colours = (t.value, t.value) if isinstance(t, Constant) else (t.color0, t.color1)
            rows.append((CHECKERBOARD, *colours, 0, 0, 0, NEAREST, REPEAT))
    columns = list(zip(*rows)) if rows else [()] * 8
    return TextureTable(
        slot=slot,
        kind=np.asarray(columns[0], dtype=np.int32),
        to_uv=np.asarray([t.to_uv for t in textures], dtype=np.float32).reshape(-1, 3, 3),
        color0=np.asarray(columns[1], dtype=np.float32).reshape(-1, 3),
        color1=np.asarray(columns[2], dtype=np.float32).reshape(-1, 3),
        offset=np.asarray(columns[3], dtype=np.int32),
        width=np.asarray(columns[4], dtype=np.int32),
        height=np.asarray(columns[5], dtype=np.int32),
        filter=np.asarray(columns[6], dtype=np.int32),
        wrap=np.asarray(columns[7], dtype=np.int32),
        texels=np.concatenate([b.reshape(-1, 3) for b in bitmaps]) if bitmaps else np.zeros((1, 3), np.float32),
    )
