"""Textures on the device: material parameters that vary over a surface with its (u, v).

Every texture of a scene sits in one ``TextureData``: per texture its ``kind``, its ``to_uv``
transform (the 2D affine map applied to the surface's uv first, Mitsuba 3's ``to_uv``, as a 3x3
matrix acting on ``(u, v, 1)``) and its parameters; the texels of every bitmap lie end to end in
``texels`` (linear RGB, row-major, row 0 the top row of the file: uv (0, 0) is the image's top
left corner, as in Mitsuba 3). ``slot[m, s]`` is the texture of parameter ``s`` (``ALBEDO``,
``SPECULAR``, ..., ``NORMAL_MAP``) of material ``m``, -1 where the parameter is the material's
constant (for ``NORMAL_MAP``: where the material has no normal map).

Kinds, as Mitsuba 3's plugins of the same names:

- ``CHECKERBOARD``: ``color0`` where the fractional parts of u and v are both above one half or
  both not, ``color1`` elsewhere (squares of side 1/2 in uv);
- ``BITMAP``: an image of ``width`` x ``height`` texels from ``offset`` in ``texels``, looked up
  with ``filter`` ``NEAREST`` (the texel holding ``uv * size``) or ``BILINEAR`` (texel centres at
  ``(i + 1/2) / size``, the four nearest weighted), integer texel coordinates outside the image
  taken back by ``wrap`` ``REPEAT``, ``MIRROR`` or ``CLAMP``;
- ``MESH_ATTRIBUTE``: a mesh's vertex or face attribute (Mitsuba 3's ``mesh_attribute``): attribute
  ``offset`` of the ``width`` the scene has, per triangle corner in ``corners`` (a face attribute
  the same at its three corners), interpolated by the hit's barycentric coordinates and times
  ``color0`` (its ``scale``); its uv and ``to_uv`` are not used.

Textures are evaluated at a ``TextureEvalContext`` (pbrt's name): the hit's uv, and for a triangle
its index and barycentric coordinates. ``texture_rgb`` evaluates a texture (linear RGB),
``texture_float`` one number of it (Mitsuba 3's ``eval_1``: a bitmap's luminance),
``material_rgb`` / ``material_float`` a material parameter, textured or constant.
"""

import warp as wp

CHECKERBOARD = wp.constant(0)
BITMAP = wp.constant(1)
MESH_ATTRIBUTE = wp.constant(2)

NEAREST = wp.constant(0)
BILINEAR = wp.constant(1)

REPEAT = wp.constant(0)
MIRROR = wp.constant(1)
CLAMP = wp.constant(2)

ALBEDO = wp.constant(0)
SPECULAR = wp.constant(1)
REFLECTANCE = wp.constant(2)
ROUGHNESS = wp.constant(3)
OPACITY = wp.constant(4)
NORMAL_MAP = wp.constant(5)
TRANSMITTANCE = wp.constant(6)
ROUGHNESS_V = wp.constant(7)
WEIGHT = wp.constant(8)
BUMP_MAP = wp.constant(9)
METALLIC = wp.constant(10)
SPEC_TRANS = wp.constant(11)
SPEC_TINT = wp.constant(12)
SHEEN = wp.constant(13)
SHEEN_TINT = wp.constant(14)
FLATNESS = wp.constant(15)
CLEARCOAT = wp.constant(16)
CLEARCOAT_GLOSS = wp.constant(17)
ANISOTROPY = wp.constant(18)
DIFF_TRANS = wp.constant(19)
EMISSION = wp.constant(20)
SLOTS = (
    "albedo",
    "specular",
    "reflectance",
    "roughness",
    "opacity",
    "normal_map",
    "transmittance",
    "roughness_v",
    "weight",
    "bump_map",
    "metallic",
    "spec_trans",
    "spec_tint",
    "sheen",
    "sheen_tint",
    "flatness",
    "clearcoat",
    "clearcoat_gloss",
    "anisotropy",
    "diff_trans",
    "emission",
)
"""The material parameters a texture can give, in slot order (``slot[m, s]``); ``normal_map`` is
a raw bitmap of tangent-space normals (``wrt.kernels.hit.perturbed_normal``), not a BSDF parameter;
``transmittance`` a thin dielectric's only (a dielectric's is an absorption per unit length, a
property of its volume; whitted's filtered shadow rays, which compute no uv, take its mean);
``roughness_v`` an anisotropic material's alpha along the bitangent (``roughness`` the one along the
tangent); ``weight`` a blend's (its second material's share); ``bump_map`` a height field, whose
gradient (``texture_float_grad``) tilts the shading normal (``wrt.kernels.hit.bumped_normal``);
``metallic`` to ``diff_trans`` a principled material's numbers (``wrt.kernels.materials.principled``);
``emission`` the radiance (W/(m^2 sr)) any material emits from its front (``material_emission``)."""


@wp.struct
class TextureData:
    slot: wp.array2d(dtype=wp.int32)  # (materials, len(SLOTS)): texture index, -1 for the constant
    kind: wp.array(dtype=wp.int32)
    to_uv: wp.array(dtype=wp.mat33)  # affine map of (u, v, 1) applied before the lookup
    color0: wp.array(dtype=wp.vec3)  # checkerboard colours, linear RGB
    color1: wp.array(dtype=wp.vec3)
    offset: wp.array(dtype=wp.int32)  # bitmap: its first texel in ``texels``
    width: wp.array(dtype=wp.int32)
    height: wp.array(dtype=wp.int32)
    filter: wp.array(dtype=wp.int32)  # NEAREST or BILINEAR
    wrap: wp.array(dtype=wp.int32)  # REPEAT, MIRROR or CLAMP
    texels: wp.array(dtype=wp.vec3)  # every bitmap's texels, linear RGB, row-major from the top row
    corners: wp.array(dtype=wp.vec3)  # mesh attributes: (triangle, corner, attribute) row-major; empty without


@wp.struct
class TextureEvalContext:
    """Where a texture is evaluated (``wrt.kernels.traverse.texture_context``): the surface's
    texture coordinates ``uv`` and, at a triangle, its index ``prim`` in ``tri_verts`` (-1
    elsewhere) and the barycentric coordinates ``bary`` = (b1, b2) of its second and third corners."""

    uv: wp.vec2
    prim: wp.int32
    bary: wp.vec2


@wp.func
def uv_context(uv: wp.vec2) -> TextureEvalContext:
    """The context of texture coordinates ``uv`` alone (no triangle)."""
    ctx = TextureEvalContext()
    ctx.uv = uv
    ctx.prim = -1
    return ctx


@wp.func
def wrap_texel(i: wp.int32, size: wp.int32, wrap: wp.int32) -> wp.int32:
    """Integer texel coordinate ``i`` taken into ``0 .. size - 1``: periodically (``REPEAT``),
    reflected at each edge with the edge texel repeated (``MIRROR``), or clamped (``CLAMP``)."""
    if wrap == CLAMP:
        return wp.clamp(i, 0, size - 1)
    if wrap == REPEAT:
        r = i % size
        return wp.where(r < 0, r + size, r)
    j = wp.where(i < 0, -i - 1, i) % (2 * size)
    return wp.where(j < size, j, 2 * size - 1 - j)


@wp.func
def texel(textures: TextureData, t: wp.int32, x: wp.int32, y: wp.int32) -> wp.vec3:
    """Texel ``(x, y)`` (column, row from the top; any integers, wrapped) of bitmap ``t``."""
    w = textures.width[t]
    h = textures.height[t]
    wrap = textures.wrap[t]
    return textures.texels[textures.offset[t] + wrap_texel(y, h, wrap) * w + wrap_texel(x, w, wrap)]


@wp.func
def bilinear_footprint(textures: TextureData, t: wp.int32, st: wp.vec2):
    """``(i, j, fx, fy)``: the top-left texel of the four a bilinear lookup of bitmap ``t`` at ``st``
    (already through ``to_uv``) weighs, and the lookup's fractional offsets from its centre."""
    x = st[0] * float(textures.width[t]) - 0.5
    y = st[1] * float(textures.height[t]) - 0.5
    x0 = wp.floor(x)
    y0 = wp.floor(y)
    return int(x0), int(y0), x - x0, y - y0


@wp.func
def bitmap_rgb(textures: TextureData, t: wp.int32, uv: wp.vec2) -> wp.vec3:
    """Bitmap ``t`` at ``uv`` (already through ``to_uv``), nearest or bilinear."""
    if textures.filter[t] == NEAREST:
        x = uv[0] * float(textures.width[t])
        y = uv[1] * float(textures.height[t])
        return texel(textures, t, int(wp.floor(x)), int(wp.floor(y)))
    i, j, fx, fy = bilinear_footprint(textures, t, uv)
    top = (1.0 - fx) * texel(textures, t, i, j) + fx * texel(textures, t, i + 1, j)
    bottom = (1.0 - fx) * texel(textures, t, i, j + 1) + fx * texel(textures, t, i + 1, j + 1)
    return (1.0 - fy) * top + fy * bottom


LUMINANCE = wp.constant(wp.vec3(0.212671, 0.715160, 0.072169))  # Mitsuba 3's (Rec. 709) weights


@wp.func
def texture_st(textures: TextureData, t: wp.int32, uv: wp.vec2) -> wp.vec2:
    """Surface coordinates ``uv`` through texture ``t``'s ``to_uv``."""
    m = textures.to_uv[t]
    return wp.vec2(m[0, 0] * uv[0] + m[0, 1] * uv[1] + m[0, 2], m[1, 0] * uv[0] + m[1, 1] * uv[1] + m[1, 2])


@wp.func
def mesh_attribute_rgb(textures: TextureData, t: wp.int32, ctx: TextureEvalContext) -> wp.vec3:
    """Mesh-attribute texture ``t`` at ``ctx``: its corners' values interpolated by the barycentric
    coordinates, times its scale; zero off a triangle (a host check keeps such lookups out)."""
    if ctx.prim < 0:
        return wp.vec3(0.0)
    stride = textures.width[t]
    first = 3 * ctx.prim * stride + textures.offset[t]
    b1 = ctx.bary[0]
    b2 = ctx.bary[1]
    value = (
        (1.0 - b1 - b2) * textures.corners[first]
        + b1 * textures.corners[first + stride]
        + b2 * textures.corners[first + 2 * stride]
    )
    return wp.cw_mul(value, textures.color0[t])


@wp.func
def texture_rgb(textures: TextureData, t: wp.int32, ctx: TextureEvalContext) -> wp.vec3:
    """Texture ``t`` at ``ctx``: linear RGB."""
    kind = textures.kind[t]
    if kind == MESH_ATTRIBUTE:
        return mesh_attribute_rgb(textures, t, ctx)
    st = texture_st(textures, t, ctx.uv)
    if kind == CHECKERBOARD:
        above_u = st[0] - wp.floor(st[0]) > 0.5
        above_v = st[1] - wp.floor(st[1]) > 0.5
        return wp.where(above_u == above_v, textures.color0[t], textures.color1[t])
    return bitmap_rgb(textures, t, st)


@wp.func
def texture_float(textures: TextureData, t: wp.int32, ctx: TextureEvalContext) -> float:
    """Texture ``t`` at ``ctx`` as one number, as Mitsuba 3's ``eval_1``: a bitmap's luminance
    (Rec. 709 weights), the mean of a checkerboard colour's channels (Mitsuba's ``eval_1`` of a
    checkerboard also swaps its two colours, against its own ``eval``: not followed here), a
    one-channel mesh attribute's value (held in all three channels)."""
    weights = wp.vec3(1.0 / 3.0)
    if textures.kind[t] == BITMAP:
        weights = LUMINANCE
    return wp.dot(texture_rgb(textures, t, ctx), weights)


@wp.func
def texture_float_grad(textures: TextureData, t: wp.int32, ctx: TextureEvalContext) -> wp.vec2:
    """The gradient (d/du, d/dv) of ``texture_float`` of texture ``t`` at ``ctx``, as Mitsuba 3's
    bitmap ``eval_1_grad``: a bilinear bitmap's, from its four texels' luminances, per texel
    spacing times the bitmap's size, taken back through ``to_uv``'s linear part by its transpose
    before that scaling (Mitsuba's order, the chain rule where ``to_uv`` neither rotates nor
    shears); zero for a nearest-filtered bitmap and for other kinds."""
    if textures.kind[t] != BITMAP or textures.filter[t] == NEAREST:
        return wp.vec2(0.0)
    i, j, fx, fy = bilinear_footprint(textures, t, texture_st(textures, t, ctx.uv))
    w = float(textures.width[t])
    h = float(textures.height[t])
    f00 = wp.dot(texel(textures, t, i, j), LUMINANCE)
    f10 = wp.dot(texel(textures, t, i + 1, j), LUMINANCE)
    f01 = wp.dot(texel(textures, t, i, j + 1), LUMINANCE)
    f11 = wp.dot(texel(textures, t, i + 1, j + 1), LUMINANCE)
    dfx = (1.0 - fy) * (f10 - f00) + fy * (f11 - f01)
    dfy = (1.0 - fx) * (f01 - f00) + fx * (f11 - f10)
    m = textures.to_uv[t]
    return wp.vec2(w * (m[0, 0] * dfx + m[1, 0] * dfy), h * (m[0, 1] * dfx + m[1, 1] * dfy))


@wp.func
def material_rgb(
    textures: TextureData, m: wp.int32, slot: wp.int32, ctx: TextureEvalContext, constant: wp.vec3
) -> wp.vec3:
    """Colour parameter ``slot`` of material ``m`` at ``ctx``: its texture's value, or ``constant``
    (the material's own value) where it has none."""
    t = textures.slot[m, slot]
    if t < 0:
        return constant
    return texture_rgb(textures, t, ctx)


@wp.func
def material_float(
    textures: TextureData, m: wp.int32, slot: wp.int32, ctx: TextureEvalContext, constant: float
) -> float:
    """Number parameter ``slot`` of material ``m`` at ``ctx`` (roughness): its texture's
    ``texture_float``, or ``constant`` where it has none."""
    t = textures.slot[m, slot]
    if t < 0:
        return constant
    return texture_float(textures, t, ctx)
