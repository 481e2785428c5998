"""An independent float64 numpy model of Mitsuba 3's ``principled`` and ``principledthin`` BSDFs.

It follows Mitsuba 3's ``src/bsdfs/principled.cpp``, ``principledthin.cpp`` and ``principledhelpers.h``
(and the GGX ``MicrofacetDistribution``, ``fresnel`` and ``warp`` routines they call) formula by formula,
as the installed 3.9.1 build (scalar_rgb) behaves, so that a kernel can be tested against it without
Mitsuba. ``eval``, ``pdf``, ``sample`` and ``mitsuba_dict`` are ``principled``'s; ``thin_eval``,
``thin_pdf``, ``thin_sample`` and ``thin_mitsuba_dict`` are ``principledthin``'s (its own section below).

Conventions
-----------
* Local shading coordinates: z is the shading normal, x the tangent ``s`` (the direction of
  ``alpha_x``, the rougher one when ``anisotropic`` > 0), y the bitangent ``t``.
* Mitsuba's naming: ``wi`` points toward the viewer (Mitsuba's ``si.wi``), ``wo`` is the other
  direction (the light's, for radiance). ``wi.z < 0`` is the back (inside) side of the surface.
* ``eval`` is Mitsuba's ``eval``: the BSDF value times the cosine factor ``|cos theta_o| = |wo.z|``, in
  radiance transport mode (the transmission lobe carries the ``1 / eta_path**2`` factor).
* ``pdf`` is the solid-angle density Mitsuba reports (its ``pdf``); ``sample`` reproduces Mitsuba's
  ``sample`` step by step: ``(wo, weight = eval / pdf, pdf)``, the weight 0 where Mitsuba deactivates
  the sample (its ``bs.wo`` and ``bs.pdf`` are still reported there, as Mitsuba does).
* ``params`` holds constant values under Mitsuba's XML names (``base_color`` three floats; the rest floats).
  A lobe switch ``has_X`` (Mitsuba's ``get_flag``) is on when ``X`` is given and nonzero.

Everything is vectorised over N direction pairs: directions are ``(N, 3)`` arrays, spectra ``(N, 3)``
RGB arrays. Only numpy is used, in float64; Mitsuba computes in float32, so agreement is ~1e-6
relative for reflection, ~1e-4 for transmission, worse only at grazing angles, in near-vanishing lobe
tails and for samples whose float32 direction error a sharp lobe amplifies.
"""

import numpy as np

INV_PI = 1.0 / np.pi
FLOAT32_EPSILON = 2.0**-24  # drjit's Epsilon<float>, used by Frame3f::sincos_phi
LUMINANCE = np.array([0.212671, 0.715160, 0.072169])  # Mitsuba's linear-sRGB luminance weights

DEFAULTS = {
    "base_color": (0.5, 0.5, 0.5),
    "roughness": 0.5,
    "anisotropic": 0.0,
    "metallic": 0.0,
    "spec_trans": 0.0,
    "specular": 0.5,
    "spec_tint": 0.0,
    "sheen": 0.0,
    "sheen_tint": 0.0,
    "flatness": 0.0,
    "clearcoat": 0.0,
    "clearcoat_gloss": 0.0,
    "main_specular_sampling_rate": 1.0,
    "clearcoat_sampling_rate": 1.0,  # the code's default (the plugin's documentation says 0.0)
    "diffuse_reflectance_sampling_rate": 1.0,
}
FLAGGED = ("anisotropic", "spec_trans", "sheen", "sheen_tint", "flatness", "spec_tint", "metallic", "clearcoat")


# ----------------------------------------------------------------------------------------------------
# Parameters
# ----------------------------------------------------------------------------------------------------


def plugin_dict(plugin: str, names, params: dict) -> dict:
    """The dict for ``mi.load_dict`` of BSDF ``plugin`` with ``params`` (only the keys given, as floats;
    ``base_color`` as an ``rgb``); a key outside ``names`` is an error."""
    out = {"type": plugin}
    for key, value in params.items():
        if key not in names:
            raise KeyError(f"{plugin} has no parameter {key!r}")
        if key == "base_color":
            out[key] = {"type": "rgb", "value": [float(c) for c in value]}
        else:
            out[key] = float(value)
    return out


def mitsuba_dict(params: dict) -> dict:
    """The dict for ``mi.load_dict`` of the principled BSDF ``params`` (only the keys given, as floats)."""
    return plugin_dict("principled", (*DEFAULTS, "eta"), params)


def has_flag(params: dict, name: str) -> bool:
    """Mitsuba's ``get_flag``: the lobe/feature ``name`` is on when given as a nonzero float."""
    return name in params and float(params[name]) != 0.0


def eta_of(params: dict) -> float:
    """The relative IOR: ``eta`` as given, else from ``specular`` (default 0.5), with Mitsuba's guards.

    With ``spec_trans`` on, ``eta == 1`` becomes 1.001 and ``specular == 0`` becomes 1e-3 (an index-matched
    interface is not plausible for transmission); ``eta = 2 / (1 - sqrt(0.08 specular)) - 1``.
    """
    if "eta" in params and "specular" in params:
        raise ValueError("give either eta or specular, not both")
    spec_trans = has_flag(params, "spec_trans")
    if "eta" in params:
        eta = float(params["eta"])
        return 1.001 if spec_trans and eta == 1.0 else eta
    specular = float(params.get("specular", DEFAULTS["specular"]))
    if spec_trans and specular == 0.0:
        specular = 1e-3
    return 2.0 / (1.0 - np.sqrt(0.08 * specular)) - 1.0


def dist_params(roughness: float, anisotropic: float, has_anisotropic: bool) -> tuple[float, float]:
    """The GGX roughnesses ``(alpha_x, alpha_y)`` (``calc_dist_params``): roughness**2, stretched by
    ``aspect = sqrt(1 - 0.9 anisotropic)`` (x rougher) when ``has_anisotropic``, at least 0.001."""
    r2 = roughness**2
    if not has_anisotropic:
        a = max(0.001, r2)
        return a, a
    aspect = np.sqrt(1.0 - 0.9 * anisotropic)
    return max(0.001, r2 / aspect), max(0.001, r2 * aspect)


def alphas(params: dict) -> tuple[float, float]:
    """The GGX roughnesses ``(alpha_x, alpha_y)`` of ``params``' roughness and anisotropy (``dist_params``)."""
    roughness = float(params.get("roughness", DEFAULTS["roughness"]))
    return dist_params(roughness, float(params.get("anisotropic", 0.0)), has_flag(params, "anisotropic"))


def material(params: dict) -> dict:
    """Every constant the lobes need, with Mitsuba's defaults and flags (a flag off zeroes its weight)."""
    p = {k: params.get(k, v) for k, v in DEFAULTS.items()}
    m = {k: (float(p[k]) if has_flag(params, k) else 0.0) for k in FLAGGED}
    m["has"] = {k: has_flag(params, k) for k in FLAGGED}
    m["base_color"] = np.asarray(p["base_color"], dtype=np.float64).reshape(3)
    m["roughness"] = float(p["roughness"])
    m["clearcoat_gloss"] = float(p["clearcoat_gloss"])
    m["spec_srate"] = float(p["main_specular_sampling_rate"])
    m["clearcoat_srate"] = float(p["clearcoat_sampling_rate"])
    m["diffuse_srate"] = float(p["diffuse_reflectance_sampling_rate"])
    m["eta"] = eta_of(params)
    m["alpha_x"], m["alpha_y"] = alphas(params)
    m["clearcoat_alpha"] = (1.0 - m["clearcoat_gloss"]) * 0.1 + m["clearcoat_gloss"] * 0.001  # lerp(0.1, 0.001, gloss)
    m["brdf"] = (1.0 - m["metallic"]) * (1.0 - m["spec_trans"])  # weight of the diffuse (BRDF) lobes
    m["bsdf"] = (1.0 - m["metallic"]) * m["spec_trans"]  # weight of the transmission (BSDF) lobe
    m["lum"] = float(LUMINANCE @ m["base_color"])
    return m


# ----------------------------------------------------------------------------------------------------
# Vector helpers
# ----------------------------------------------------------------------------------------------------


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of two (N, 3) arrays."""
    return np.einsum("ij,ij->i", a, b)


def normalize(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` scaled to unit length (NaN for a zero row, as in Mitsuba)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=1, keepdims=True)


def mulsign(v: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``v`` times the sign (bit) of ``s`` per row: drjit's ``mulsign`` (-0 counts as negative)."""
    return v * np.copysign(1.0, s)[:, None]


def reflect(wi: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Mirror ``wi`` about the microfacet normal ``m``: ``2 (wi . m) m - wi``."""
    return 2.0 * dot(wi, m)[:, None] * m - wi


def refract(wi: np.ndarray, m: np.ndarray, cos_theta_t: np.ndarray, eta_ti: np.ndarray) -> np.ndarray:
    """Refract ``wi`` through ``m`` (Mitsuba's ``refract``, with ``cos_theta_t, eta_ti`` from ``fresnel``)."""
    return m * (dot(wi, m) * eta_ti + cos_theta_t)[:, None] - wi * eta_ti[:, None]


def rows(v, n: int | None = None, width: int = 3) -> np.ndarray:
    """``v`` as a float64 (N, width) array (a single row is broadcast to ``n`` rows)."""
    v = np.atleast_2d(np.asarray(v, dtype=np.float64))
    return np.broadcast_to(v, (n if n is not None else v.shape[0], width)).copy()


# ----------------------------------------------------------------------------------------------------
# Fresnel
# ----------------------------------------------------------------------------------------------------


def fresnel(cos_theta_i: np.ndarray, eta: float):
    """Unpolarised dielectric Fresnel reflectance (Mitsuba's ``fresnel``).

    ``cos_theta_i`` is taken against a normal on the outside (``eta``'s side); a negative value means the
    ray arrives from inside. Returns ``(F, cos_theta_t, eta_it, eta_ti)``: ``cos_theta_t`` signed opposite
    to ``cos_theta_i`` (0 under total internal reflection, where F = 1), ``eta_it`` the relative IOR
    along the ray and ``eta_ti`` its reciprocal. F = 0 when ``eta == 1``, F = 1 at ``cos_theta_i == 0``.
    """
    outside = cos_theta_i >= 0.0
    eta_it = np.where(outside, eta, 1.0 / eta)
    eta_ti = np.where(outside, 1.0 / eta, eta)
    cos_t2 = 1.0 - (1.0 - cos_theta_i**2) * eta_ti**2
    cos_i = np.abs(cos_theta_i)
    cos_t = np.sqrt(np.maximum(cos_t2, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        a_s = (cos_i - eta_it * cos_t) / (cos_i + eta_it * cos_t)
        a_p = (cos_t - eta_it * cos_i) / (cos_t + eta_it * cos_i)
    F = 0.5 * (a_s**2 + a_p**2)
    if eta == 1.0:
        F = np.zeros_like(F)
    F = np.where(cos_i == 0.0, 0.0 if eta == 1.0 else 1.0, F)
    return F, -np.copysign(cos_t, cos_theta_i), eta_it, eta_ti


def schlick_weight(cos_i: np.ndarray) -> np.ndarray:
    """``(1 - cos_i)**5`` with ``1 - cos_i`` clamped to [0, 1]."""
    return np.clip(1.0 - cos_i, 0.0, 1.0) ** 5


def schlick_R0(eta: np.ndarray) -> np.ndarray:
    """Normal-incidence reflectance ``((eta - 1) / (eta + 1))**2``."""
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def schlick_F(R0, cos_theta_i: np.ndarray, eta: float) -> np.ndarray:
    """Mitsuba's ``calc_schlick``: ``R0 + (1 - R0) schlick_weight(c)``, (N, ...) for R0 scalar or (3,).

    ``c`` is ``|cos_theta_i|`` when the ray goes into the denser side (``eta_it > 1``), else the
    transmitted cosine (Snell's law, 0 past the critical angle).
    """
    outside = cos_theta_i >= 0.0
    eta_it = np.where(outside, eta, 1.0 / eta)
    eta_ti = np.where(outside, 1.0 / eta, eta)
    cos_t = np.sqrt(np.maximum(1.0 - (1.0 - cos_theta_i**2) * eta_ti**2, 0.0))
    w = np.where(eta_it > 1.0, schlick_weight(np.abs(cos_theta_i)), schlick_weight(cos_t))
    R0 = np.asarray(R0, dtype=np.float64)
    if R0.ndim == 0:
        return w * (1.0 - R0) + R0
    return w[:, None] * (1.0 - R0) + R0  # R0 is (3,) or (N, 3)


def tint(mat: dict) -> np.ndarray:
    """``base_color / luminance`` (white where the luminance is 0): the hue of the tints."""
    return mat["base_color"] / mat["lum"] if mat["lum"] > 0.0 else np.ones(3)


def principled_fresnel(mat: dict, F_dielectric: np.ndarray, cos_theta_i: np.ndarray, front: np.ndarray) -> np.ndarray:
    """The main reflection lobe's (N, 3) Fresnel factor (``principled_fresnel``).

    Front side: ``(1 - metallic)(1 - spec_tint) F_dielectric`` plus Schlick terms, ``metallic`` toward
    ``base_color`` and ``(1 - metallic) spec_tint`` toward the tint times ``R0(eta_it)``.
    Back side: ``bsdf F_dielectric`` (no tint, no metal; zero when ``spec_trans`` is off).
    ``cos_theta_i = wi . wh``.
    """
    eta = mat["eta"]
    F_schlick = np.zeros((len(cos_theta_i), 3))
    if mat["has"]["metallic"]:
        F_schlick += mat["metallic"] * schlick_F(mat["base_color"], cos_theta_i, eta)
    if mat["has"]["spec_tint"]:
        eta_it = np.where(cos_theta_i >= 0.0, eta, 1.0 / eta)
        F0 = tint(mat)[None, :] * schlick_R0(eta_it)[:, None]
        F_schlick += (1.0 - mat["metallic"]) * mat["spec_tint"] * schlick_F(F0, cos_theta_i, eta)
    F_front = (1.0 - mat["metallic"]) * (1.0 - mat["spec_tint"]) * F_dielectric[:, None] + F_schlick
    return np.where(front[:, None], F_front, mat["bsdf"] * F_dielectric[:, None])


# ----------------------------------------------------------------------------------------------------
# GGX (Mitsuba's MicrofacetDistribution, type GGX, sample_visible = true)
# ----------------------------------------------------------------------------------------------------


def ggx_D(m: np.ndarray, ax: float, ay: float) -> np.ndarray:
    """Anisotropic GGX normal distribution D(m) (0 where ``D cos_theta_m <= 1e-20``)."""
    D = 1.0 / (np.pi * ax * ay * ((m[:, 0] / ax) ** 2 + (m[:, 1] / ay) ** 2 + m[:, 2] ** 2) ** 2)
    return np.where(D * m[:, 2] > 1e-20, D, 0.0)


def ggx_G1(v: np.ndarray, m: np.ndarray, ax: float, ay: float) -> np.ndarray:
    """Smith's GGX masking G1(v, m): 1 at normal incidence, 0 where v sees the back of ``m``."""
    xy_alpha_2 = (ax * v[:, 0]) ** 2 + (ay * v[:, 1]) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        G1 = 2.0 / (1.0 + np.sqrt(1.0 + xy_alpha_2 / v[:, 2] ** 2))
    G1 = np.where(xy_alpha_2 == 0.0, 1.0, G1)
    return np.where(dot(v, m) * v[:, 2] <= 0.0, 0.0, G1)


def ggx_G(wi: np.ndarray, wo: np.ndarray, m: np.ndarray, ax: float, ay: float) -> np.ndarray:
    """Smith's separable shadowing-masking G(wi, wo, m) = G1(wi, m) G1(wo, m)."""
    return ggx_G1(wi, m, ax, ay) * ggx_G1(wo, m, ax, ay)


def ggx_visible_pdf(wi: np.ndarray, m: np.ndarray, ax: float, ay: float) -> np.ndarray:
    """Density of visible-normal sampling: ``D(m) G1(wi, m) |wi . m| / wi.z`` (``wi.z > 0``)."""
    return ggx_D(m, ax, ay) * ggx_G1(wi, m, ax, ay) * np.abs(dot(wi, m)) / wi[:, 2]


def square_to_uniform_disk_concentric(u: np.ndarray) -> np.ndarray:
    """Shirley-Chiu concentric map of (N, 2) unit-square samples to the unit disk (Dave Cline's form)."""
    x, y = 2.0 * u[:, 0] - 1.0, 2.0 * u[:, 1] - 1.0
    q13 = np.abs(x) < np.abs(y)
    r = np.where(q13, y, x)
    rp = np.where(q13, x, y)
    with np.errstate(invalid="ignore", divide="ignore"):
        phi = 0.25 * np.pi * rp / r
    phi = np.where(q13, 0.5 * np.pi - phi, phi)
    phi = np.where((x == 0.0) & (y == 0.0), 0.0, phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


def square_to_cosine_hemisphere(u: np.ndarray) -> np.ndarray:
    """Cosine-weighted hemisphere directions (z >= 0) from (N, 2) samples, via the concentric disk."""
    p = square_to_uniform_disk_concentric(u)
    z = np.sqrt(np.maximum(1.0 - (p**2).sum(axis=1), 0.0))
    return np.column_stack([p, z])


def sincos_phi(v: np.ndarray):
    """``(sin phi, cos phi)`` of ``v`` (Frame3f::sincos_phi: (0, 1) when ``v`` is nearly along z)."""
    sin_theta_2 = v[:, 0] ** 2 + v[:, 1] ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        xy = np.clip(v[:, :2] / np.sqrt(sin_theta_2)[:, None], -1.0, 1.0)
    degenerate = np.abs(sin_theta_2) <= 4.0 * FLOAT32_EPSILON
    return np.where(degenerate, 0.0, xy[:, 1]), np.where(degenerate, 1.0, xy[:, 0])


def ggx_sample_visible_11(cos_theta_i: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Slopes of visible normals of the alpha = 1 GGX surface seen at ``cos_theta_i`` ((N, 2))."""
    p = square_to_uniform_disk_concentric(u)
    s = 0.5 * (1.0 + cos_theta_i)
    px = p[:, 0]
    py = np.sqrt(np.maximum(1.0 - px**2, 0.0)) * (1.0 - s) + p[:, 1] * s
    pz = np.sqrt(np.maximum(1.0 - px**2 - py**2, 0.0))
    sin_theta_i = np.sqrt(np.maximum(1.0 - cos_theta_i**2, 0.0))
    norm = 1.0 / (sin_theta_i * py + cos_theta_i * pz)
    return np.stack([(cos_theta_i * py - sin_theta_i * pz) * norm, px * norm], axis=1)


def ggx_sample(wi: np.ndarray, u: np.ndarray, ax: float, ay: float) -> np.ndarray:
    """A GGX microfacet normal ``m`` (z > 0) visible from ``wi`` (``wi.z > 0``): stretch, sample, unstretch."""
    wi_p = normalize(wi * np.array([ax, ay, 1.0]))
    sin_phi, cos_phi = sincos_phi(wi_p)
    slope = ggx_sample_visible_11(wi_p[:, 2], u)
    sx = (cos_phi * slope[:, 0] - sin_phi * slope[:, 1]) * ax
    sy = (sin_phi * slope[:, 0] + cos_phi * slope[:, 1]) * ay
    return normalize(np.stack([-sx, -sy, np.ones_like(sx)], axis=1))


# ----------------------------------------------------------------------------------------------------
# Clearcoat: GTR1 distribution and its separable GGX masking with alpha 0.25
# ----------------------------------------------------------------------------------------------------


def gtr1_D(m: np.ndarray, alpha: float) -> np.ndarray:
    """Berry's GTR1 distribution ``(a2 - 1) / (pi log(a2) (1 + (a2 - 1) cos2))`` (0 where tiny)."""
    a2 = alpha**2
    D = (a2 - 1.0) / (np.pi * np.log(a2) * (1.0 + (a2 - 1.0) * m[:, 2] ** 2))
    return np.where(D * m[:, 2] > 1e-20, D, 0.0)


def gtr1_pdf(m: np.ndarray, alpha: float) -> np.ndarray:
    """Density of ``gtr1_sample``: ``D(m) cos_theta_m`` (0 below the horizon)."""
    return np.where(m[:, 2] < 0.0, 0.0, m[:, 2] * gtr1_D(m, alpha))


def gtr1_sample(u: np.ndarray, alpha: float) -> np.ndarray:
    """A GTR1 normal from (N, 2) samples: ``phi = 2 pi u0``, ``cos2 = (1 - a2**(1 - u1)) / (1 - a2)``."""
    phi = 2.0 * np.pi * u[:, 0]
    a2 = alpha**2
    cos2 = (1.0 - a2 ** (1.0 - u[:, 1])) / (1.0 - a2)
    sin_t = np.sqrt(np.maximum(1.0 - cos2, 0.0))
    cos_t = np.sqrt(np.maximum(cos2, 0.0))
    return np.stack([np.cos(phi) * sin_t, np.sin(phi) * sin_t, cos_t], axis=1)


def smith_ggx1(v: np.ndarray, wh: np.ndarray, alpha: float) -> np.ndarray:
    """Isotropic GGX G1 of the clearcoat (``smith_ggx1``): 1 at ``v.z == 1``, 0 on ``wh``'s back."""
    cos2 = v[:, 2] ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        G1 = 2.0 / (1.0 + np.sqrt(1.0 + alpha**2 * (1.0 - cos2) / cos2))
    G1 = np.where(v[:, 2] == 1.0, 1.0, G1)
    return np.where(dot(v, wh) * v[:, 2] <= 0.0, 0.0, G1)


# ----------------------------------------------------------------------------------------------------
# Shared pieces of eval, pdf and sample
# ----------------------------------------------------------------------------------------------------


def half_vector(wi: np.ndarray, wo: np.ndarray, reflect_mask: np.ndarray, eta_path: np.ndarray) -> np.ndarray:
    """The generalised half vector ``normalize(wi + eta' wo)`` (eta' = 1 for reflection, else
    ``eta_path``), flipped to the outside (z >= 0; a -0 z flips too)."""
    wh = normalize(wi + wo * np.where(reflect_mask, 1.0, eta_path)[:, None])
    return mulsign(wh, wh[:, 2])


def mac_mic_compatible(m: np.ndarray, wi: np.ndarray, wo: np.ndarray, cos_theta_i: np.ndarray, reflection: bool):
    """Whether micro normal ``m`` (turned to ``wi``'s side) faces ``wi`` and faces (reflection) or
    turns its back on (transmission) ``wo``: Mitsuba's ``mac_mic_compatibility``."""
    m_side = mulsign(m, cos_theta_i)
    facing_wi = dot(wi, m_side) > 0.0
    return facing_wi & ((dot(wo, m_side) > 0.0) if reflection else (dot(wo, -m_side) > 0.0))


def lobe_probabilities(mat: dict, F: np.ndarray, front: np.ndarray):
    """Normalised selection probabilities ``(spec_reflect, spec_trans, clearcoat, diffuse)``.

    Front side: ``srate (1 - bsdf (1 - F))``, ``srate bsdf (1 - F)``, ``clearcoat srate / 4`` and
    ``brdf srate``; back side: F and ``1 - F`` (the latter only with ``spec_trans`` on), nothing else.
    ``F`` is the dielectric Fresnel at ``wi . m`` (the sampled normal in ``sample``, the half vector
    in ``pdf``).
    """
    srate, bsdf = mat["spec_srate"], mat["bsdf"]
    p_sr = np.where(front, srate * (1.0 - bsdf * (1.0 - F)), F)
    p_st = np.where(front, srate * bsdf * (1.0 - F), 1.0 - F) if mat["has"]["spec_trans"] else np.zeros_like(F)
    p_cc = (
        np.where(front, 0.25 * mat["clearcoat"] * mat["clearcoat_srate"], 0.0) if mat["has"]["clearcoat"] else 0.0 * F
    )
    p_diff = np.where(front, mat["brdf"] * mat["diffuse_srate"], 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        rcp_total = 1.0 / (p_sr + p_st + p_cc + p_diff)
    return p_sr * rcp_total, p_st * rcp_total, p_cc * rcp_total, p_diff * rcp_total


# ----------------------------------------------------------------------------------------------------
# The lobes of eval (each (N, 3), cosine factor included, zero where the lobe is inactive)
# ----------------------------------------------------------------------------------------------------


def geometry(mat: dict, wi: np.ndarray, wo: np.ndarray) -> dict:
    """What eval and pdf share for the pairs ``(wi, wo)``: cosines, side and reflection masks, the
    path's ``eta_path`` (``eta`` from the front, ``1 / eta`` from the back), the outward half vector
    ``wh`` and ``wi . wh``, ``wo . wh``, the dielectric Fresnel ``F = fresnel(wi . wh, eta)`` (the
    viewer's side) and the two ``mac_mic_compatible`` masks."""
    cos_i, cos_o = wi[:, 2], wo[:, 2]
    front = cos_i > 0.0
    reflect_mask = cos_i * cos_o > 0.0
    eta_path = np.where(front, mat["eta"], 1.0 / mat["eta"])
    wh = half_vector(wi, wo, reflect_mask, eta_path)
    wi_h, wo_h = dot(wi, wh), dot(wo, wh)
    return {
        "cos_i": cos_i,
        "cos_o": cos_o,
        "active": cos_i != 0.0,  # perfectly grazing wi: nothing
        "front": front,
        "reflect": reflect_mask,
        "refract": cos_i * cos_o < 0.0,
        "eta_path": eta_path,
        "wh": wh,
        "wi_h": wi_h,
        "wo_h": wo_h,
        "F": fresnel(wi_h, mat["eta"])[0],
        "compat_reflect": mac_mic_compatible(wh, wi, wo, cos_i, True),
        "compat_refract": mac_mic_compatible(wh, wi, wo, cos_i, False),
    }


def microfacet_reflection(g: dict, wi: np.ndarray, wo: np.ndarray, ax: float, ay: float) -> np.ndarray:
    """The GGX reflection factor without Fresnel, ``D(wh) G(wi, wo, wh) / (4 |cos theta_i|)`` ((N,))."""
    return ggx_D(g["wh"], ax, ay) * ggx_G(wi, wo, g["wh"], ax, ay) / (4.0 * np.abs(g["cos_i"]))


def specular_reflection(mat: dict, g: dict, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """Main GGX reflection, both sides: ``principled_fresnel D G / (4 |cos theta_i|)``."""
    on = g["active"] & g["reflect"] & g["compat_reflect"] & (g["F"] > 0.0)
    F = principled_fresnel(mat, g["F"], g["wi_h"], g["front"])
    return np.where(on[:, None], F * microfacet_reflection(g, wi, wo, mat["alpha_x"], mat["alpha_y"])[:, None], 0.0)


def specular_transmission(mat: dict, g: dict, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """GGX transmission (Walter et al.), both sides, radiance mode (``1 / eta_path**2``), tinted by
    ``sqrt(base_color)`` and weighted by ``bsdf``; ``1 - F`` uses the viewer side's Fresnel."""
    on = mat["has"]["spec_trans"] & g["active"] & (mat["bsdf"] > 0.0) & g["refract"] & g["compat_refract"]
    on &= g["F"] < 1.0
    D = ggx_D(g["wh"], mat["alpha_x"], mat["alpha_y"])
    G = ggx_G(wi, wo, g["wh"], mat["alpha_x"], mat["alpha_y"])
    eta_path, wi_h, wo_h = g["eta_path"], g["wi_h"], g["wo_h"]
    scale = (1.0 / eta_path) ** 2
    value = np.abs(
        scale * (1.0 - g["F"]) * D * G * eta_path**2 * wi_h * wo_h / (g["cos_i"] * (wi_h + eta_path * wo_h) ** 2)
    )
    return np.where(on[:, None], np.sqrt(mat["base_color"]) * mat["bsdf"] * value[:, None], 0.0)


def clearcoat_reflection(mat: dict, g: dict, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """Clearcoat, front side: ``clearcoat / 4 * F_schlick(0.04) D_GTR1 G_cc |cos theta_o|`` with the
    GGX ``G_cc`` of alpha 0.25; Mitsuba has no ``1 / (4 cos theta_i cos theta_o)`` factor here."""
    on = (
        mat["has"]["clearcoat"]
        & g["active"]
        & (mat["clearcoat"] > 0.0)
        & g["reflect"]
        & g["compat_reflect"]
        & g["front"]
    )
    Fcc = schlick_F(0.04, g["wi_h"], mat["eta"])
    Dcc = gtr1_D(g["wh"], mat["clearcoat_alpha"])
    Gcc = smith_ggx1(wi, g["wh"], 0.25) * smith_ggx1(wo, g["wh"], 0.25)
    value = 0.25 * mat["clearcoat"] * Fcc * Dcc * Gcc * np.abs(g["cos_o"])
    return np.where(on, value, 0.0)[:, None] * np.ones(3)


def diffuse_active(mat: dict, g: dict) -> np.ndarray:
    """Where the diffuse lobe is on: front-side reflection with ``brdf > 0``."""
    return g["active"] & (mat["brdf"] > 0.0) & g["reflect"] & g["front"]


def diffuse_reflection(mat: dict, g: dict) -> np.ndarray:
    """Burley's diffuse with retro-reflection (``Rr = 2 roughness (wo . wh)**2``), blended by
    ``flatness`` with the Hanrahan-Krueger-like fake subsurface, times ``brdf base_color / pi``."""
    cos_i, cos_o = np.abs(g["cos_i"]), np.abs(g["cos_o"])
    Fo, Fi = schlick_weight(cos_o), schlick_weight(cos_i)
    f_diff = (1.0 - 0.5 * Fi) * (1.0 - 0.5 * Fo)
    Rr = 2.0 * mat["roughness"] * g["wo_h"] ** 2
    f_retro = Rr * (Fo + Fi + Fo * Fi * (Rr - 1.0))
    lobe = f_diff + f_retro
    if mat["has"]["flatness"]:
        Fss90 = Rr / 2.0
        Fss = (1.0 + Fo * (Fss90 - 1.0)) * (1.0 + Fi * (Fss90 - 1.0))  # lerp(1, Fss90, Fo) lerp(1, Fss90, Fi)
        f_ss = 1.25 * (Fss * (1.0 / (cos_o + cos_i) - 0.5) + 0.5)
        lobe = lobe * (1.0 - mat["flatness"]) + f_ss * mat["flatness"]
    value = mat["brdf"] * (cos_o * INV_PI * lobe)[:, None] * mat["base_color"]
    return np.where(diffuse_active(mat, g)[:, None], value, 0.0)


def sheen_lobe(mat: dict, g: dict) -> np.ndarray:
    """The sheen before its lobe weight: ``sheen schlick_weight(|wo . wh|) c_sheen |cos theta_o|``
    ((N, 3)), ``c_sheen = lerp(1, tint, sheen_tint)``."""
    c_sheen = np.ones(3)
    if mat["has"]["sheen_tint"]:
        c_sheen = (1.0 - mat["sheen_tint"]) + tint(mat) * mat["sheen_tint"]
    value = mat["sheen"] * schlick_weight(np.abs(g["wo_h"])) * np.abs(g["cos_o"])
    return value[:, None] * c_sheen


def sheen_reflection(mat: dict, g: dict) -> np.ndarray:
    """Sheen, front side: ``(1 - metallic) sheen_lobe``. Only where the diffuse lobe is on (``brdf >
    0``): the scalar variants evaluate it inside the diffuse branch, so it vanishes at ``spec_trans == 1``."""
    if not mat["has"]["sheen"]:
        return np.zeros((len(g["cos_i"]), 3))
    on = diffuse_active(mat, g) & (mat["sheen"] > 0.0) & (1.0 - mat["metallic"] > 0.0)
    return np.where(on[:, None], (1.0 - mat["metallic"]) * sheen_lobe(mat, g), 0.0)


# ----------------------------------------------------------------------------------------------------
# eval, pdf, sample
# ----------------------------------------------------------------------------------------------------


def eval(params: dict, wi, wo) -> np.ndarray:  # noqa: A001 - Mitsuba's name
    """Mitsuba's ``principled`` eval: (N, 3) RGB BSDF value times ``|cos theta_o|`` (radiance mode),
    the sum of the main reflection, transmission, clearcoat, diffuse and sheen lobes."""
    mat = material(params)
    wi = rows(wi)
    wo = rows(wo, len(wi))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        g = geometry(mat, wi, wo)
        value = specular_reflection(mat, g, wi, wo) + diffuse_reflection(mat, g) + sheen_reflection(mat, g)
        if mat["has"]["spec_trans"]:
            value += specular_transmission(mat, g, wi, wo)
        if mat["has"]["clearcoat"]:
            value += clearcoat_reflection(mat, g, wi, wo)
    return np.where(g["active"][:, None], value, 0.0)


def half_vector_jacobian(mat: dict, g: dict) -> np.ndarray:
    """``|d wh / d wo|``: ``1 / (4 |wo . wh|)`` for reflection, ``eta_path**2 |wo . wh| / (wi . wh +
    eta_path wo . wh)**2`` for transmission (the reflection form everywhere when ``spec_trans`` is off)."""
    wi_h, wo_h, eta_path = g["wi_h"], g["wo_h"], g["eta_path"]
    if not mat["has"]["spec_trans"]:
        return np.abs(1.0 / (4.0 * wo_h))
    transmission = eta_path**2 * wo_h / (wi_h + eta_path * wo_h) ** 2
    return np.abs(np.where(g["reflect"], 1.0 / (4.0 * wo_h), transmission))


def pdf(params: dict, wi, wo) -> np.ndarray:
    """Mitsuba's ``principled`` pdf: (N,) solid-angle density of ``sample`` as Mitsuba reports it.

    The mixture of the lobes' densities with ``lobe_probabilities`` evaluated with the Fresnel at the
    half vector of ``(wi, wo)``; the GGX density is the visible-normal one seen from ``wi`` turned
    to the outside, times the half-vector Jacobian. The diffuse term is counted for every reflection
    pair (its probability is 0 on the back side). Note: on the back side with ``spec_trans`` off the
    result is the reflection density although ``eval`` is 0 there (``sample`` never goes there), and
    NaN if moreover ``eta == 1`` (F = 0: 0 / 0 probabilities), as in Mitsuba.
    """
    mat = material(params)
    wi = rows(wi)
    wo = rows(wo, len(wi))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        g = geometry(mat, wi, wo)
        p_sr, p_st, p_cc, p_diff = lobe_probabilities(mat, g["F"], g["front"])
        jacobian = half_vector_jacobian(mat, g)
        spec_pdf = ggx_visible_pdf(mulsign(wi, g["cos_i"]), g["wh"], mat["alpha_x"], mat["alpha_y"])
        reflect_ok = g["compat_reflect"] & g["reflect"]
        result = np.where(reflect_ok, p_sr * spec_pdf * jacobian, 0.0)
        result = result + np.where(g["reflect"], p_diff * INV_PI * g["cos_o"], 0.0)
        if mat["has"]["spec_trans"]:
            refract_ok = g["compat_refract"] & g["refract"]
            result = result + np.where(refract_ok, p_st * spec_pdf * jacobian, 0.0)
        if mat["has"]["clearcoat"]:
            cc_pdf = gtr1_pdf(g["wh"], mat["clearcoat_alpha"])
            result = result + np.where(reflect_ok, p_cc * cc_pdf * jacobian, 0.0)
    return np.where(g["active"], result, 0.0)


def select_lobe(mat: dict, active: np.ndarray, sample1: np.ndarray, p_st, p_cc, p_diff):
    """Masks ``(diffuse, clearcoat, transmission, reflection)`` that ``sample1`` selects, the intervals
    of [0, 1) in that order (reflection takes the rest)."""
    pick_diffuse = active & (sample1 < p_diff)
    cur = p_diff
    pick_clearcoat = mat["has"]["clearcoat"] & active & (sample1 >= cur) & (sample1 < cur + p_cc)
    cur = cur + p_cc
    pick_trans = mat["has"]["spec_trans"] & active & (sample1 >= cur) & (sample1 < cur + p_st)
    pick_reflect = active & (sample1 >= cur + p_st)
    return pick_diffuse, pick_clearcoat, pick_trans, pick_reflect


def sample(params: dict, wi, sample1, sample2):
    """Mitsuba's ``principled`` sample: ``(wo (N, 3), weight (N, 3), pdf (N,))``.

    One GGX visible normal ``m`` is drawn from ``sample2`` (seen from ``wi`` turned outside) and the
    Fresnel at ``wi . m`` sets the lobe probabilities (``lobe_probabilities``); ``sample1`` picks, in
    order, diffuse (cosine hemisphere from ``sample2``), clearcoat (GTR1 normal from ``sample2``),
    transmission (refraction through ``m``), reflection (about ``m``).

    ``pdf`` is always ``pdf(params, wi, wo)`` of the returned ``wo`` (the mixture, not the selected
    lobe's density), as Mitsuba 3.9.1 reports ``bs.pdf``. The sample is dropped (weight 0) where
    ``wi.z == 0`` or on the back side without ``spec_trans`` (no lobe selected: ``wo`` and ``pdf`` 0),
    where the new direction is on the wrong side or ``m`` faces away from it (``wo`` and ``pdf`` as
    computed, weight 0), and where ``pdf <= 0``; elsewhere ``weight = eval / pdf``.
    """
    mat = material(params)
    wi = rows(wi)
    n = len(wi)
    sample1 = np.broadcast_to(np.asarray(sample1, dtype=np.float64), (n,))
    sample2 = rows(sample2, n, 2)
    eta, ax, ay = mat["eta"], mat["alpha_x"], mat["alpha_y"]
    cos_i = wi[:, 2]
    active = cos_i != 0.0
    front = cos_i > 0.0

    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        m_spec = ggx_sample(mulsign(wi, cos_i), sample2, ax, ay)
        F, cos_theta_t, _, eta_ti = fresnel(dot(wi, m_spec), eta)
        active &= front | (mat["bsdf"] > 0.0)
        _, p_st, p_cc, p_diff = lobe_probabilities(mat, F, front)

        pick_diffuse, pick_clearcoat, pick_trans, pick_reflect = select_lobe(mat, active, sample1, p_st, p_cc, p_diff)

        wo = np.zeros((n, 3))
        ok = np.ones(n, dtype=bool)

        wo_r = reflect(wi, m_spec)
        wo = np.where(pick_reflect[:, None], wo_r, wo)
        ok &= ~pick_reflect | (mac_mic_compatible(m_spec, wi, wo_r, cos_i, True) & (cos_i * wo_r[:, 2] > 0.0))

        if mat["has"]["spec_trans"]:
            wo_t = refract(wi, m_spec, cos_theta_t, eta_ti)
            wo = np.where(pick_trans[:, None], wo_t, wo)
            ok &= ~pick_trans | (mac_mic_compatible(m_spec, wi, wo_t, cos_i, False) & (cos_i * wo_t[:, 2] < 0.0))

        if mat["has"]["clearcoat"]:
            m_cc = gtr1_sample(sample2, mat["clearcoat_alpha"])
            wo_c = reflect(wi, m_cc)
            wo = np.where(pick_clearcoat[:, None], wo_c, wo)
            ok &= ~pick_clearcoat | (mac_mic_compatible(m_cc, wi, wo_c, cos_i, True) & (cos_i * wo_c[:, 2] > 0.0))

        wo_d = square_to_cosine_hemisphere(sample2)
        wo = np.where(pick_diffuse[:, None], wo_d, wo)
        ok &= ~pick_diffuse | (cos_i * wo_d[:, 2] > 0.0)

        active &= ok
        density = pdf(params, wi, wo)  # Mitsuba's bs.pdf: the pdf of wo, even where the sample is dropped
        active &= density > 0.0
        weight = np.where(active[:, None], eval(params, wi, wo) / density[:, None], 0.0)

    return wo, weight, density


# ----------------------------------------------------------------------------------------------------
# principledthin: Mitsuba 3's thin principled BSDF (src/bsdfs/principledthin.cpp)
#
# A two-sided sheet with no interior: eval, pdf and sample turn both directions to the viewer's side
# (``mulsign(., wi.z)``, all three components), so ``f(wi, wo) = f(-wi, -wo)``, and work on the front.
# Its lobes: GGX reflection ``spec_trans F_thin D G / (4 cos_i)``; GGX "transmission" ``spec_trans
# base_color (1 - F) D' G' / (4 cos_i)``, a reflection mirrored through the sheet (``wo.z -> -wo.z``),
# with the distribution of roughness ``(0.65 eta - 0.35) roughness``; Burley's diffuse (and flatness,
# sheen) weighted by ``(1 - spec_trans)(1 - diff_trans)``; Lambertian transmission ``(1 - spec_trans)
# diff_trans base_color / pi``. ``diff_trans`` is halved (the parameter's range is 0-2); there is no
# 1 / eta**2 factor (bs.eta = 1). Without ``spec_trans`` there is no specular lobe at all.
# ----------------------------------------------------------------------------------------------------

THIN_DEFAULTS = {
    "base_color": (0.5, 0.5, 0.5),
    "roughness": 0.5,
    "anisotropic": 0.0,
    "spec_trans": 0.0,
    "spec_tint": 0.0,
    "sheen": 0.0,
    "sheen_tint": 0.0,
    "flatness": 0.0,
    "eta": 1.5,  # a number here (no specular alternative, no guard at 1)
    "diff_trans": 0.0,  # 0-2, halved internally
    "specular_reflectance_sampling_rate": 1.0,
    "specular_transmittance_sampling_rate": 1.0,
    "diffuse_reflectance_sampling_rate": 1.0,
    "diffuse_transmittance_sampling_rate": 1.0,
}
THIN_FLAGGED = ("anisotropic", "spec_trans", "sheen", "sheen_tint", "flatness", "spec_tint", "diff_trans")


def thin_mitsuba_dict(params: dict) -> dict:
    """The dict for ``mi.load_dict`` of the principledthin BSDF ``params`` (only the keys given)."""
    return plugin_dict("principledthin", THIN_DEFAULTS, params)


def thin_material(params: dict) -> dict:
    """principledthin's constants under ``material``'s keys where the meaning is the same.

    ``brdf`` is the weight of the diffuse reflection (and sheen), ``(1 - spec_trans)(1 - diff_trans)``
    with ``diff_trans`` already halved; ``alpha_x, alpha_y`` the reflection's GGX roughnesses,
    ``trans_alpha_x, trans_alpha_y`` the transmission's (roughness scaled by ``0.65 eta - 0.35``).
    """
    p = {k: params.get(k, v) for k, v in THIN_DEFAULTS.items()}
    m = {k: (float(p[k]) if has_flag(params, k) else 0.0) for k in THIN_FLAGGED}
    m["has"] = {k: has_flag(params, k) for k in THIN_FLAGGED}
    m["diff_trans"] /= 2.0
    m["base_color"] = np.asarray(p["base_color"], dtype=np.float64).reshape(3)
    m["roughness"] = float(p["roughness"])
    m["eta"] = float(p["eta"])
    m["spec_reflect_srate"] = float(p["specular_reflectance_sampling_rate"])
    m["spec_trans_srate"] = float(p["specular_transmittance_sampling_rate"])
    m["diff_reflect_srate"] = float(p["diffuse_reflectance_sampling_rate"])
    m["diff_trans_srate"] = float(p["diffuse_transmittance_sampling_rate"])
    aniso = (m["anisotropic"], m["has"]["anisotropic"])
    m["alpha_x"], m["alpha_y"] = dist_params(m["roughness"], *aniso)
    m["trans_alpha_x"], m["trans_alpha_y"] = dist_params((0.65 * m["eta"] - 0.35) * m["roughness"], *aniso)
    m["brdf"] = (1.0 - m["spec_trans"]) * (1.0 - m["diff_trans"])
    m["lum"] = float(LUMINANCE @ m["base_color"])
    return m


def thin_front(wi: np.ndarray, wo: np.ndarray):
    """``(wi, wo)`` both multiplied by the sign of ``wi.z`` (``mulsign``): the viewer on the front."""
    return mulsign(wi, wi[:, 2]), mulsign(wo, wi[:, 2])


def thin_geometry(mat: dict, wi: np.ndarray, wo: np.ndarray) -> dict:
    """``geometry``'s quantities for a front-side pair (``thin_front``): the half vector ``wh =
    normalize(wi + wo_r)`` of ``wo_r``, ``wo`` mirrored to the front, for reflection and transmission
    alike; ``wo_h = wo . wh`` (Mitsuba's ``cos_theta_d``, negative for transmission), ``wor_h = wo_r . wh``
    (its Jacobian's), the dielectric ``F = fresnel(wi . wh, eta)`` and the ``mac_mic_compatible`` masks
    of ``wh`` with ``wo`` itself (not ``wo_r``)."""
    cos_i, cos_o = wi[:, 2], wo[:, 2]
    wo_r = wo * np.array([1.0, 1.0, 0.0]) + np.abs(cos_o)[:, None] * np.array([0.0, 0.0, 1.0])
    wh = normalize(wi + wo_r)
    wi_h = dot(wi, wh)
    return {
        "cos_i": cos_i,
        "cos_o": cos_o,
        "active": cos_i != 0.0,  # perfectly grazing wi: nothing
        "front": cos_i > 0.0,  # everywhere active
        "reflect": cos_o > 0.0,
        "refract": cos_o < 0.0,
        "wh": wh,
        "wi_h": wi_h,
        "wo_h": dot(wo, wh),
        "wor_h": dot(wo_r, wh),
        "F": fresnel(wi_h, mat["eta"])[0],
        "compat_reflect": mac_mic_compatible(wh, wi, wo, cos_i, True),
        "compat_refract": mac_mic_compatible(wh, wi, wo, cos_i, False),
    }


def thin_fresnel(mat: dict, F_dielectric: np.ndarray, cos_theta_i: np.ndarray) -> np.ndarray:
    """The reflection's (N, 3) Fresnel factor (``thin_fresnel``): ``lerp(F_dielectric, F_schlick,
    spec_tint)``, ``F_schlick`` the Schlick term of ``R0 = tint R0(eta)`` (0 without ``spec_tint``)."""
    F = (1.0 - mat["spec_tint"]) * F_dielectric[:, None] * np.ones(3)
    if mat["has"]["spec_tint"]:
        F0 = tint(mat) * schlick_R0(mat["eta"])
        F = F + mat["spec_tint"] * schlick_F(F0, cos_theta_i, mat["eta"])
    return F


def thin_specular_reflection(mat: dict, g: dict, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """GGX reflection: ``spec_trans thin_fresnel D G / (4 cos theta_i)`` (only with ``spec_trans``)."""
    on = g["active"] & (mat["spec_trans"] > 0.0) & g["reflect"] & g["compat_reflect"]
    F = thin_fresnel(mat, g["F"], g["wi_h"])
    value = mat["spec_trans"] * F * microfacet_reflection(g, wi, wo, mat["alpha_x"], mat["alpha_y"])[:, None]
    return np.where(on[:, None], value, 0.0)


def thin_specular_transmission(mat: dict, g: dict, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """The mirrored GGX reflection through the sheet: ``spec_trans base_color (1 - F) D' G' / (4 cos
    theta_i)`` with the scaled roughness, ``G'`` of ``wo`` itself; ``wh`` must face ``wi`` and turn its
    back on ``wo`` (so only part of the mirrored lobe survives)."""
    on = g["active"] & (mat["spec_trans"] > 0.0) & g["refract"] & g["compat_refract"]
    factor = microfacet_reflection(g, wi, wo, mat["trans_alpha_x"], mat["trans_alpha_y"])
    value = mat["spec_trans"] * ((1.0 - g["F"]) * factor)[:, None] * mat["base_color"]
    return np.where(on[:, None], value, 0.0)


def thin_sheen(mat: dict, g: dict) -> np.ndarray:
    """Sheen: ``brdf sheen_lobe`` where the diffuse reflection is on."""
    if not mat["has"]["sheen"]:
        return np.zeros((len(g["cos_i"]), 3))
    on = diffuse_active(mat, g) & (mat["sheen"] > 0.0)
    return np.where(on[:, None], mat["brdf"] * sheen_lobe(mat, g), 0.0)


def thin_diffuse_transmission(mat: dict, g: dict) -> np.ndarray:
    """Lambertian transmission: ``(1 - spec_trans) diff_trans base_color |cos theta_o| / pi``."""
    on = g["active"] & g["refract"] & (mat["spec_trans"] < 1.0) & (mat["diff_trans"] > 0.0)
    value = (1.0 - mat["spec_trans"]) * mat["diff_trans"] * INV_PI * np.abs(g["cos_o"])
    return np.where(on[:, None], value[:, None] * mat["base_color"], 0.0)


def thin_eval(params: dict, wi, wo) -> np.ndarray:
    """Mitsuba's ``principledthin`` eval: (N, 3) RGB BSDF value times ``|cos theta_o|``, the sum of the
    specular reflection and transmission, diffuse, sheen and diffuse transmission lobes."""
    mat = thin_material(params)
    wi = rows(wi)
    wi, wo = thin_front(wi, rows(wo, len(wi)))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        g = thin_geometry(mat, wi, wo)
        value = diffuse_reflection(mat, g) + thin_sheen(mat, g)
        if mat["has"]["spec_trans"]:
            value += thin_specular_reflection(mat, g, wi, wo) + thin_specular_transmission(mat, g, wi, wo)
        if mat["has"]["diff_trans"]:
            value += thin_diffuse_transmission(mat, g)
    return np.where(g["active"][:, None], value, 0.0)


def thin_lobe_probabilities(mat: dict):
    """Normalised selection probabilities ``(spec_reflect, spec_trans, diffuse_reflect, diffuse_trans)``
    (constants: no Fresnel): ``spec_trans srate / 2`` twice, ``srate (1 - spec_trans)(1 - diff_trans)``,
    ``srate (1 - spec_trans) diff_trans``; a lobe off (``has_``) has probability 0."""
    st, dt = mat["spec_trans"], mat["diff_trans"]
    p = np.array(
        [
            st * mat["spec_reflect_srate"] / 2.0 if mat["has"]["spec_trans"] else 0.0,
            st * mat["spec_trans_srate"] / 2.0 if mat["has"]["spec_trans"] else 0.0,
            mat["diff_reflect_srate"] * (1.0 - st) * (1.0 - dt),
            mat["diff_trans_srate"] * (1.0 - st) * dt if mat["has"]["diff_trans"] else 0.0,
        ]
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        return tuple(p / p.sum())


def thin_pdf(params: dict, wi, wo) -> np.ndarray:
    """Mitsuba's ``principledthin`` pdf: (N,) solid-angle density of ``thin_sample``.

    Front-side pair (``thin_front``); both GGX terms are visible-normal densities of ``wh`` seen from
    ``wi``, each with its own roughness, times the reflection Jacobian ``1 / (4 |wo_r . wh|)``; the
    cosine-hemisphere terms are ``cos theta_o / pi`` on the reflected and ``-cos theta_o / pi`` on the
    transmitted side.
    """
    mat = thin_material(params)
    wi = rows(wi)
    wi, wo = thin_front(wi, rows(wo, len(wi)))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        g = thin_geometry(mat, wi, wo)
        p_sr, p_st, p_dr, p_dt = thin_lobe_probabilities(mat)
        result = np.where(g["reflect"], p_dr * INV_PI * g["cos_o"], 0.0)
        if mat["has"]["spec_trans"]:
            jacobian = np.abs(1.0 / (4.0 * g["wor_h"]))
            reflect_pdf = ggx_visible_pdf(wi, g["wh"], mat["alpha_x"], mat["alpha_y"])
            trans_pdf = ggx_visible_pdf(wi, g["wh"], mat["trans_alpha_x"], mat["trans_alpha_y"])
            result = result + np.where(g["compat_reflect"] & g["reflect"], p_sr * reflect_pdf * jacobian, 0.0)
            result = result + np.where(g["compat_refract"] & g["refract"], p_st * trans_pdf * jacobian, 0.0)
        if mat["has"]["diff_trans"]:
            result = result + np.where(g["refract"], p_dt * INV_PI * -g["cos_o"], 0.0)
    return np.where(g["active"], result, 0.0)


def thin_sample(params: dict, wi, sample1, sample2):
    """Mitsuba's ``principledthin`` sample: ``(wo (N, 3), weight (N, 3), pdf (N,))``.

    ``sample1`` picks, in order, specular reflection (a GGX visible normal from ``sample2``, ``wo``
    reflected about it), specular transmission (the same with the scaled roughness, then ``wo.z ->
    -wo.z``), cosine-hemisphere reflection and cosine-hemisphere transmission (``-wo``), all on the
    front and turned back to ``wi``'s side at the end. ``pdf`` is ``thin_pdf`` of the returned ``wo``;
    the weight is 0 where ``wi.z == 0`` or no lobe is picked (``wo`` and ``pdf`` 0), where a specular
    ``wo`` lands on the wrong side or ``m`` is not ``mac_mic_compatible`` with it, and where ``pdf <= 0``;
    elsewhere ``weight = thin_eval / pdf``. A rejected specular sample still reports its ``wo`` and its
    nonzero ``pdf``: the source passes the rejection mask to ``pdf``, but 3.9.1's scalar ``pdf`` and
    ``eval`` ignore their ``active`` argument (only the weight's final ``& active`` zeroes it).
    """
    mat = thin_material(params)
    wi = rows(wi)
    n = len(wi)
    sample1 = np.broadcast_to(np.asarray(sample1, dtype=np.float64), (n,))
    sample2 = rows(sample2, n, 2)
    cos_i = wi[:, 2]
    active = cos_i != 0.0
    wi_f = mulsign(wi, cos_i)
    p_sr, p_st, p_dr, _ = thin_lobe_probabilities(mat)
    has_st, has_dt = mat["has"]["spec_trans"], mat["has"]["diff_trans"]
    pick_sr = has_st & active & (sample1 < p_sr)
    pick_st = has_st & active & (sample1 >= p_sr) & (sample1 < p_sr + p_st)
    pick_dr = active & (sample1 >= p_sr + p_st) & (sample1 < p_sr + p_st + p_dr)
    pick_dt = has_dt & active & (sample1 >= p_sr + p_st + p_dr)

    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        wo = np.zeros((n, 3))
        ok = np.ones(n, dtype=bool)
        if has_st:
            m_r = ggx_sample(wi_f, sample2, mat["alpha_x"], mat["alpha_y"])
            wo_r = reflect(wi_f, m_r)
            wo = np.where(pick_sr[:, None], wo_r, wo)
            ok &= ~pick_sr | (mac_mic_compatible(m_r, wi_f, wo_r, wi_f[:, 2], True) & (wo_r[:, 2] > 0.0))
            m_t = ggx_sample(wi_f, sample2, mat["trans_alpha_x"], mat["trans_alpha_y"])
            wo_t = reflect(wi_f, m_t) * np.array([1.0, 1.0, -1.0])
            wo = np.where(pick_st[:, None], wo_t, wo)
            ok &= ~pick_st | (mac_mic_compatible(m_t, wi_f, wo_t, wi_f[:, 2], False) & (wo_t[:, 2] < 0.0))
        wo_d = square_to_cosine_hemisphere(sample2)
        wo = np.where(pick_dr[:, None], wo_d, wo)
        wo = np.where(pick_dt[:, None], -wo_d, wo)
        wo = mulsign(wo, cos_i)

        active &= ok
        density = thin_pdf(params, wi, wo)
        active &= density > 0.0
        weight = np.where(active[:, None], thin_eval(params, wi, wo) / density[:, None], 0.0)

    return wo, weight, density
