"""The whitted integrator (kernels/whitted.py) against closed forms, at the origin and far from it."""

import numpy as np
import pytest
from conftest import make_scene

import wrt

TOP = {"origin": [0, 3, 4], "look_at": [0, 0, 0], "fov": 60}


def whitted(shapes, materials, lights=(), camera=TOP, size=(64, 48), device="cpu", **render):
    settings = {"width": size[0], "height": size[1], "integrator": "whitted", **render}
    scene = make_scene(shapes, materials=materials, lights=list(lights), camera=camera, render=settings)
    return wrt.render(scene, device=device)


def diffuse(name, albedo):
    return {"name": name, "albedo": list(albedo)}


def lambert_point(P, normal, albedo, light_pos, intensity):
    """albedo/pi * intensity * cos(theta) / d^2 in float64 (0 where the light is behind the surface)."""
    to = np.asarray(light_pos) - P
    d2 = (to**2).sum(-1)
    cos = np.maximum((to * normal).sum(-1) / np.sqrt(d2), 0)
    return np.asarray(albedo) / np.pi * np.asarray(intensity) * (cos / d2)[..., None]


def test_point_light_on_diffuse_plane_is_exact(device):
    albedo, intensity, L = [0.5, 0.6, 0.7], [10.0, 20.0, 5.0], [0.3, 2.0, 0.5]
    r = whitted(
        [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m"}],
        [diffuse("m", albedo)],
        [{"type": "point", "position": L, "intensity": intensity}],
        device=device,
    )
    hit = r.aovs["object_id"] == 0
    expected = lambert_point(r.aovs["position"], np.array([0, 1.0, 0]), albedo, L, intensity)
    np.testing.assert_allclose(r.rgb[hit], expected[hit], rtol=1e-4)


def test_directional_and_spot_lights():
    albedo = [0.8, 0.8, 0.8]
    plane = [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m"}]
    direction = np.array([1.0, -2.0, 0.5])
    r = whitted(
        plane,
        [diffuse("m", albedo)],
        [{"type": "directional", "direction": direction.tolist(), "irradiance": [2.0, 1.0, 3.0]}],
    )
    cos = 2.0 / np.linalg.norm(direction)
    lit = r.rgb[r.aovs["object_id"] == 0]
    np.testing.assert_allclose(
        lit, np.broadcast_to(np.array([2.0, 1.0, 3.0]) * 0.8 / np.pi * cos, lit.shape), rtol=1e-5
    )
    spot = {
        "type": "spot",
        "position": [0, 2, 0],
        "direction": [0, -1, 0],
        "intensity": [30, 30, 30],
        "cutoff_angle": 30.0,
        "beam_width": 20.0,
    }
    r = whitted(plane, [diffuse("m", albedo)], [spot])
    P = r.aovs["position"]
    angle = np.degrees(np.arctan2(np.hypot(P[..., 0], P[..., 2]), 2.0))
    falloff = np.clip((30.0 - angle) / 10.0, 0, 1)
    expected = lambert_point(P, np.array([0, 1.0, 0]), albedo, [0, 2, 0], [30, 30, 30]) * falloff[..., None]
    hit = r.aovs["object_id"] == 0
    np.testing.assert_allclose(r.rgb[hit], expected[hit], rtol=1e-4, atol=1e-6)
    assert (falloff[hit] == 0).any() and (falloff[hit] == 1).any() and ((falloff[hit] > 0) & (falloff[hit] < 1)).any()


def test_phong_lobe_closed_form():
    kd, ks, n = np.array([0.3, 0.2, 0.1]), np.array([0.5, 0.6, 0.7]), 20.0
    L, intensity = np.array([0.5, 2.0, 1.0]), np.array([8.0, 8.0, 8.0])
    r = whitted(
        [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "p"}],
        [{"name": "p", "type": "phong", "albedo": kd.tolist(), "specular": ks.tolist(), "exponent": n}],
        [{"type": "point", "position": L.tolist(), "intensity": intensity.tolist()}],
    )
    P = r.aovs["position"].astype(np.float64)
    N = np.array([0, 1.0, 0])
    wi = L - P
    d2 = (wi**2).sum(-1, keepdims=True)
    wi /= np.sqrt(d2)
    wo = np.array(TOP["origin"]) - P
    wo /= np.linalg.norm(wo, axis=-1, keepdims=True)
    mirror = -wi + 2 * wi[..., 1:2] * N
    cos_alpha = np.maximum((mirror * wo).sum(-1, keepdims=True), 0)
    f = kd / np.pi + ks * (n + 2) / (2 * np.pi) * cos_alpha**n
    expected = f * intensity * wi[..., 1:2] / d2
    hit = r.aovs["object_id"] == 0
    np.testing.assert_allclose(r.rgb[hit], expected[hit], rtol=2e-4)


def test_mirror_returns_reflectance_times_the_wall_radiance(device):
    """A mirror (plane z = 0) facing a lit diffuse wall (plane z = 6): each mirror pixel equals
    reflectance x the wall's closed-form radiance at the reflected point."""
    rho, albedo, L, intensity = (
        np.array([0.9, 0.7, 0.5]),
        [0.6, 0.6, 0.6],
        np.array([0.0, 0.0, 3.0]),
        [20.0, 20.0, 20.0],
    )
    cam = {"origin": [0.0, 1.0, 4.0], "look_at": [0.0, 0.0, 0.0], "fov": 40}
    r = whitted(
        [
            {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1], "material": "mirror"},
            {"type": "plane", "point": [0, 0, 6], "normal": [0, 0, -1], "material": "wall"},
        ],
        [{"name": "mirror", "type": "mirror", "reflectance": rho.tolist()}, diffuse("wall", albedo)],
        [{"type": "point", "position": L.tolist(), "intensity": intensity}],
        camera=cam,
        device=device,
    )
    on_mirror = r.aovs["object_id"] == 0
    P = r.aovs["position"].astype(np.float64)
    d = P - np.array(cam["origin"])
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    d[..., 2] *= -1  # reflected about the mirror's normal
    t = (6.0 - P[..., 2]) / d[..., 2]
    W = P + t[..., None] * d  # where the reflected ray meets the wall
    wall = lambert_point(W, np.array([0, 0, -1.0]), albedo, L, intensity)
    np.testing.assert_allclose(r.rgb[on_mirror], rho * wall[on_mirror], rtol=1e-4)


SLAB = {
    "type": "mesh",
    "file": "examples/meshes/cube.stl",
    "material": "glass",
    "transform": {"scale": [40.0, 40.0, 0.5]},
}
EMITTER = {"type": "plane", "point": [0, 0, -3], "normal": [0, 0, 1], "material": "light"}


@pytest.mark.parametrize(
    "max_depth, min_throughput, expected",
    [
        (3, 1e-4, lambda F: (1 - F) ** 2),  # one pass straight through, no internal reflections
        (64, 0.0, lambda F: (1 - F) / (1 + F)),  # every internal reflection: (1-F)^2 sum F^2k
    ],
)
def test_glass_slab_at_normal_incidence(max_depth, min_throughput, expected):
    n = 1.5
    F = ((n - 1) / (n + 1)) ** 2
    L = np.array([1.0, 2.0, 3.0])
    r = whitted(
        [SLAB, EMITTER],
        [
            {"name": "glass", "type": "dielectric", "ior": n},
            {"name": "light", "albedo": [0, 0, 0], "emission": L.tolist()},
        ],
        camera={"origin": [0, 0, 5], "look_at": [0, 0, 0], "fov": 10},
        size=(1, 1),
        max_depth=max_depth,
        min_throughput=min_throughput,
    )
    np.testing.assert_allclose(r.rgb[0, 0], expected(F) * L, rtol=1e-5)


def test_beer_lambert_through_a_slab():
    """Transmittance T per unit over thickness 0.5: (1-F)^2 T^0.5 at normal incidence, no internal bounces."""
    n, T = 1.5, np.array([0.2, 0.5, 0.9])
    F = ((n - 1) / (n + 1)) ** 2
    r = whitted(
        [SLAB, EMITTER],
        [
            {"name": "glass", "type": "dielectric", "ior": n, "transmittance": T.tolist()},
            {"name": "light", "albedo": [0, 0, 0], "emission": [1, 1, 1]},
        ],
        camera={"origin": [0, 0, 5], "look_at": [0, 0, 0], "fov": 10},
        size=(1, 1),
        max_depth=3,
    )
    np.testing.assert_allclose(r.rgb[0, 0], (1 - F) ** 2 * T**0.5, rtol=1e-4)


def glass_furnace(offset, ior=1.5, extra=(), size=(48, 36)):
    """Clear glass spheres (one holding an air bubble) under a uniform background of 1, no lights.
    Energy is only redistributed, so every pixel must be 1 minus what the tree's cuts drop: with
    40 segments and branches cut under 1e-5, under 1e-3 (with 12 segments, up to 0.6% at
    near-grazing entry; with no throughput cut the tree hits its 512-segment bound)."""
    o = np.asarray(offset, dtype=float)
    shapes = [
        {"type": "sphere", "center": (o + [-0.6, 0, 0]).tolist(), "radius": 0.5, "material": "glass"},
        {"type": "sphere", "center": (o + [0.6, 0, 0]).tolist(), "radius": 0.5, "material": "glass"},
        {"type": "sphere", "center": (o + [0.6, 0.1, 0]).tolist(), "radius": 0.2, "material": "air"},
        *extra,
    ]
    return whitted(
        shapes,
        [{"name": "glass", "type": "dielectric", "ior": ior}, {"name": "air", "type": "dielectric", "ior": 1.0}],
        camera={"origin": (o + [0, 0, 3]).tolist(), "look_at": o.tolist(), "fov": 40},
        size=size,
        background=[1.0, 1.0, 1.0],
        max_depth=40,
        min_throughput=1e-5,
    )


@pytest.mark.parametrize("offset", [[0, 0, 0], [1e4, -1e4, 1e4]], ids=["origin", "far"])
def test_clear_glass_conserves_energy_without_speckles(offset):
    r = glass_furnace(offset)
    assert np.isfinite(r.rgb).all()
    assert r.rgb.max() <= 1.0 + 1e-5  # energy never increases
    assert r.rgb.min() >= 1.0 - 1e-3, f"{(r.rgb < 1 - 1e-3).sum()} pixels lost energy (self-hits?)"


def test_ior_one_is_invisible():
    """An object of ior 1.0 (same as the exterior) changes nothing: the image equals the empty scene."""
    shapes = [
        {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "floor"},
        {"type": "sphere", "center": [0.3, 0, 0], "radius": 0.8, "material": "ghost"},
    ]
    mats = [diffuse("floor", [0.5, 0.5, 0.5]), {"name": "ghost", "type": "dielectric", "ior": 1.0}]
    lights = [{"type": "point", "position": [1, 3, 2], "intensity": [10, 10, 10]}]
    with_ghost = whitted(
        shapes, mats, lights, camera={"origin": [0, 1, 4], "look_at": [0, 0, 0]}, dielectric_shadows="filtered"
    )
    without = whitted(shapes[:1], mats, lights, camera={"origin": [0, 1, 4], "look_at": [0, 0, 0]})
    np.testing.assert_allclose(with_ghost.rgb, without.rgb, atol=1e-6)


def test_opaque_and_filtered_shadows_of_glass():
    shapes = [
        {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"},
        {"type": "sphere", "center": [0, 1, 0], "radius": 0.5, "material": "glass"},
    ]
    mats = [
        diffuse("floor", [0.5, 0.5, 0.5]),
        {"name": "glass", "type": "dielectric", "ior": 1.5, "transmittance": [0.5, 1.0, 1.0]},
    ]
    lights = [{"type": "point", "position": [0, 3, 0], "intensity": [10, 10, 10]}]
    cam = {"origin": [0, 4, 4], "look_at": [0, 0, 0], "fov": 30}
    opaque = whitted(shapes, mats, lights, camera=cam, size=(48, 48))
    filtered = whitted(shapes, mats, lights, camera=cam, size=(48, 48), dielectric_shadows="filtered")
    P = filtered.aovs["position"].astype(np.float64)
    # the straight segment floor -> light crosses the sphere along a chord of length 2 sqrt(r^2 - h^2)
    u = np.array([0, 3.0, 0]) - P
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    to_center = np.array([0, 1.0, 0]) - P
    h2 = (to_center**2).sum(-1) - (to_center * u).sum(-1) ** 2
    floor = filtered.aovs["object_id"] == 0
    below = floor & (h2 < 0.25 - 0.01)
    assert below.sum() > 20 and (opaque.rgb[below] == 0).all()  # physical: the glass blocks the light
    chord = 2 * np.sqrt(np.maximum(0.25 - h2, 0))
    lit = lambert_point(P, np.array([0, 1.0, 0]), [0.5] * 3, [0, 3, 0], [10] * 3)
    expected = lit * np.stack([0.5**chord, np.ones_like(chord), np.ones_like(chord)], axis=-1)
    np.testing.assert_allclose(filtered.rgb[below], expected[below], rtol=2e-3)
    clear = floor & (h2 > 0.25 + 0.01)
    np.testing.assert_allclose(filtered.rgb[clear], lit[clear], rtol=1e-4)
    np.testing.assert_allclose(opaque.rgb[clear], lit[clear], rtol=1e-4)


@pytest.mark.parametrize("offset, rtol", [([0, 0, 0], 1e-4), ([1e4, 1e4, -1e4], 5e-3)], ids=["origin", "far"])
def test_no_shadow_acne(offset, rtol):
    """A sphere on a lit plane: every lit pixel of the plane and of the sphere matches the closed
    form (acne would leave dark speckles); shadowed plane pixels are exactly 0. Far from the
    origin float32 positions are spaced 1e-3 apart (0.2% of the sphere's radius), hence rtol; and
    the spawn offset (16 ulps of the coordinates, 0.03 there) decides shadow rays that pass the
    sphere closer than that, so those pixels are not judged."""
    o = np.asarray(offset, dtype=float)
    C, R, L, intensity = o + [0, 0.5, 0], 0.5, o + [1.0, 3.0, 1.0], [15.0, 15.0, 15.0]
    r = whitted(
        [
            {"type": "plane", "point": o.tolist(), "normal": [0, 1, 0], "material": "m"},
            {"type": "sphere", "center": C.tolist(), "radius": R, "material": "m"},
        ],
        [diffuse("m", [0.7, 0.7, 0.7])],
        [{"type": "point", "position": L.tolist(), "intensity": intensity}],
        camera={"origin": (o + [0, 2, 4]).tolist(), "look_at": (o + [0, 0.3, 0]).tolist(), "fov": 50},
        size=(96, 72),
    )
    P = r.aovs["position"].astype(np.float64)
    ids = r.aovs["object_id"]
    normal = np.where((ids == 1)[..., None], (P - C) / R, np.array([0, 1.0, 0]))
    expected = lambert_point(P, normal, [0.7] * 3, L, intensity)
    # shadow test in float64: does the segment P -> L pass through the sphere?
    to = L - P
    length = np.linalg.norm(to, axis=-1)
    u = to / length[..., None]
    s = np.clip(((C - P) * u).sum(-1), 0, length)
    clearance = np.linalg.norm(P + s[..., None] * u - C, axis=-1) - R
    plane = ids == 0
    margin = max(1e-3, 2.0 * 16 * 2.0**-24 * 3 * np.abs(o).max())  # twice the spawn offset's bound
    lit = plane & (clearance > margin)
    shadow = plane & (clearance < -margin)
    cos_sphere = ((L - P) * normal).sum(-1) / length
    sphere_lit = (ids == 1) & (cos_sphere > 0.02)
    assert lit.sum() > 1000 and shadow.sum() > 50 and sphere_lit.sum() > 100
    np.testing.assert_allclose(r.rgb[lit], expected[lit], rtol=rtol)
    np.testing.assert_allclose(r.rgb[sphere_lit], expected[sphere_lit], rtol=rtol)
    assert (r.rgb[shadow] == 0).all()


def test_no_nan_or_inf_in_degenerate_views():
    """Grazing angles, a camera exactly in a plane, rays along a plane, a camera inside glass."""
    mats = [
        diffuse("d", [0.5, 0.5, 0.5]),
        {"name": "glass", "type": "dielectric", "ior": 1.5, "transmittance": [0.8, 0.9, 1.0]},
        {"name": "mirror", "type": "mirror"},
    ]
    lights = [
        {"type": "point", "position": [0, 2, 0], "intensity": [5, 5, 5]},
        {"type": "directional", "direction": [1, 0, 0], "irradiance": [1, 1, 1]},
    ]
    scenes = [
        # the camera sits in the plane y = 0 and looks along it
        (
            [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "d"}],
            {"origin": [0, 0, 3], "look_at": [0, 0, 0]},
        ),
        # inside a glass sphere, with a mirror and a diffuse floor outside
        (
            [
                {"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "glass"},
                {"type": "plane", "point": [0, -2, 0], "normal": [0, 1, 0], "material": "mirror"},
                {"type": "triangle", "vertices": [[-3, -1.5, -3], [3, -1.5, -3], [0, 3, -3]], "material": "d"},
            ],
            {"origin": [0.1, 0.2, 0.3], "look_at": [0, 0, -1]},
        ),
        # grazing views of glass and mirror, edge-on triangle
        (
            [
                {"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "glass"},
                {"type": "triangle", "vertices": [[-2, 1, 0], [2, 1, 0], [0, 1, -4]], "material": "mirror"},
                {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "d"},
            ],
            {"origin": [0, 1.0, 5], "look_at": [0, 1.0, 0]},
        ),
    ]
    bad = 0
    for shapes, cam in scenes:
        for spp in (1, 4):
            r = whitted(shapes, mats, lights, camera=cam, size=(40, 30), spp=spp, background=[0.2, 0.3, 0.4])
            bad += int((~np.isfinite(r.rgb)).sum())
            assert r.rgb.min() >= 0
    assert bad == 0


def test_max_depth_counts_segments():
    """max_depth 1: only emitters (no direct light); 2: direct light but a mirror's reflection of a
    lit wall stays black; 3: the reflection is lit."""
    shapes = [
        {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1], "material": "mirror"},
        {"type": "plane", "point": [0, 0, 6], "normal": [0, 0, -1], "material": "wall"},
    ]
    mats = [{"name": "mirror", "type": "mirror"}, {"name": "wall", "albedo": [0.5, 0.5, 0.5]}]
    lights = [{"type": "point", "position": [0, 0, 3], "intensity": [20, 20, 20]}]
    cam = {"origin": [0, 0, 4], "look_at": [0, 0, 0], "fov": 30}
    depth = [whitted(shapes, mats, lights, camera=cam, size=(9, 9), max_depth=k).rgb.max() for k in (1, 2, 3)]
    assert depth[0] == 0 and depth[1] == 0 and depth[2] > 0.01


def slab(z_center, thickness, material):
    return {
        "type": "mesh",
        "file": "examples/meshes/cube.stl",
        "material": material,
        "transform": {"scale": [40.0, 40.0, thickness], "translate": [0.0, 0.0, z_center]},
    }


def fresnel_normal(n1, n2):
    return ((n1 - n2) / (n1 + n2)) ** 2


def through_slabs(shapes, max_depth, glass_priority=0):
    """Radiance of a unit emitter seen at normal incidence through ``shapes``; ``max_depth`` = real
    interfaces + 1 leaves no segments for internal reflections."""
    mats = [
        {"name": "water", "type": "dielectric", "ior": 1.33},
        {"name": "glass", "type": "dielectric", "ior": 1.5, "priority": glass_priority},
        {"name": "light", "albedo": [0, 0, 0], "emission": [1, 1, 1]},
    ]
    r = whitted(
        shapes + [EMITTER],
        mats,
        camera={"origin": [0, 0, 5], "look_at": [0, 0, 0], "fov": 10},
        size=(1, 1),
        max_depth=max_depth,
    )
    return r.rgb[0, 0, 0]


def test_nested_media_use_the_right_ior_pairs():
    """A glass slab inside a water slab: air|water|glass|water|air, four real interfaces."""
    value = through_slabs([slab(0.0, 2.0, "water"), slab(0.0, 0.5, "glass")], max_depth=5)
    expected = np.prod([1 - fresnel_normal(a, b) for a, b in [(1.0, 1.33), (1.33, 1.5), (1.5, 1.33), (1.33, 1.0)]])
    assert value == pytest.approx(expected, rel=1e-5)


@pytest.mark.parametrize(
    "glass_priority, interfaces",
    [
        (1, [(1.0, 1.5), (1.5, 1.33), (1.33, 1.0)]),  # glass owns the overlap: entering water there is false
        (0, [(1.0, 1.5), (1.5, 1.33), (1.33, 1.0)]),  # tie: water, entered last, owns it; leaving glass is false
    ],
)
def test_overlapping_media_follow_priority(glass_priority, interfaces):
    """Glass z in [-0.5, 0.5] overlapping water z in [-1, 0]: along the ray the real interfaces
    depend on who owns the overlap [-0.5, 0]; at normal incidence both orders give the same
    three ior pairs, but a wrong medium stack gives four or two."""
    value = through_slabs([slab(-0.5, 1.0, "water"), slab(0.0, 1.0, "glass")], 4, glass_priority)
    expected = np.prod([1 - fresnel_normal(a, b) for a, b in interfaces])
    assert value == pytest.approx(expected, rel=1e-5)


def test_overlap_priority_changes_absorption():
    """Same overlap with absorbing water: the length travelled in water differs with ownership
    (glass owns it: 0.5 units of water; water owns it: 1.0 unit)."""
    mats = [
        {"name": "water", "type": "dielectric", "ior": 1.33, "transmittance": [0.5, 0.5, 0.5]},
        {"name": "light", "albedo": [0, 0, 0], "emission": [1, 1, 1]},
    ]
    values = []
    for priority in (1, 0):
        mats_p = mats + [{"name": "glass", "type": "dielectric", "ior": 1.5, "priority": priority}]
        r = whitted(
            [slab(-0.5, 1.0, "water"), slab(0.0, 1.0, "glass"), EMITTER],
            mats_p,
            camera={"origin": [0, 0, 5], "look_at": [0, 0, 0], "fov": 10},
            size=(1, 1),
            max_depth=4,
        )
        values.append(r.rgb[0, 0, 0])
    fresnel = np.prod([1 - fresnel_normal(a, b) for a, b in [(1.0, 1.5), (1.5, 1.33), (1.33, 1.0)]])
    assert values[0] == pytest.approx(fresnel * 0.5**0.5, rel=1e-4)
    assert values[1] == pytest.approx(fresnel * 0.5**1.0, rel=1e-4)
