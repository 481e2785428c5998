"""Heterogeneous media's device functions (wrt.kernels.volumes.grid) against float64 references: the
trilinear lookup against numpy's (and Mitsuba 3's gridvolume, where installed), and delta and
ratio tracking through a chromatic grid, placed by a rotating, non-uniformly scaling transform,
against a float64 quadrature of the transmittance and of the single-scattering integral along the
same ray. Each estimate is held to 4 standard errors of its own samples."""

import math
import types

import numpy as np
import pytest
import warp as wp
from wrt.kernels.volumes import MediumData, free_flight, tracking_key, volume_transmittance
from wrt.kernels.volumes.grid import volume_lookup

from wrt.bake import _majorant_grid, bake_media
from wrt.device import _table
from wrt.meshio import transform_matrix
from wrt.scene import Medium, Volume

pytestmark = pytest.mark.usefixtures("device")

RNG = np.random.default_rng(7)
TEXELS = RNG.uniform(0.0, 1.0, size=(4, 5, 6, 3)).astype(np.float32)  # (z, y, x, rgb): a 6 x 5 x 4 grid
TEXELS[..., 2] *= 3.0  # blue denser
ALBEDO = RNG.uniform(0.2, 1.0, size=(3, 3, 3, 3)).astype(np.float32)
TO_WORLD = transform_matrix(translate=(-0.4, 0.1, -0.3), scale=(1.5, 1.0, 2.0), rotate=(20.0, -35.0, 10.0))
SCALE = 2.5


GLOW = RNG.uniform(0.0, 2.0, size=(2, 3, 4, 3)).astype(np.float32)  # an emission grid of its own resolution


def medium_table(sigma_t=TEXELS, albedo=ALBEDO, scale=SCALE, emission=(0.0, 0.0, 0.0), sigma_n=0.0):
    medium = Medium(
        name="smoke",
        type="heterogeneous",
        sigma_t=Volume(values=sigma_t, to_world=TO_WORLD),
        albedo=Volume(values=albedo, to_world=TO_WORLD),
        scale=scale,
        emission=emission if isinstance(emission, tuple) else Volume(values=emission, to_world=TO_WORLD),
        sigma_n=sigma_n,
    )
    scene = types.SimpleNamespace(media=(medium,), boundaries=())
    table = _table(MediumData, bake_media(scene, 1), wp.get_device())
    table.count = 1
    return table


def trilinear(values, to_world, points):
    """float64 trilinear lookup between texel centres, clamped (numpy)."""
    local = (np.linalg.inv(to_world) @ np.c_[points, np.ones(len(points))].T).T[:, :3]
    nz, ny, nx, _ = values.shape
    res = np.array([nx, ny, nz])
    x = np.clip(local * res - 0.5, 0.0, res - 1)
    i0 = np.minimum(np.floor(x).astype(int), res - 1)
    i1 = np.minimum(i0 + 1, res - 1)
    f = x - i0
    v = values.astype(np.float64)
    out = 0.0
    for corner in range(8):
        pick = [(corner >> k) & 1 for k in range(3)]
        idx = [np.where(pick[k], i1[:, k], i0[:, k]) for k in range(3)]
        w = np.prod([np.where(pick[k], f[:, k], 1 - f[:, k]) for k in range(3)], axis=0)
        out = out + w[:, None] * v[idx[2], idx[1], idx[0]]
    return out


@wp.kernel
def lookup(media: MediumData, volume: int, points: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = volume_lookup(media, volume, points[i])


@wp.kernel
def track(
    media: MediumData,
    o: wp.vec3,
    d: wp.vec3,
    t_max: float,
    seed: int,
    transmitted: wp.array(dtype=wp.vec3),
    passed: wp.array(dtype=wp.vec3),
    scattered: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    key = tracking_key(seed, i, 0, 1)
    transmitted[i] = volume_transmittance(media, 0, o, d, t_max, key)
    u = (float(i) + 0.5) / float(passed.shape[0])
    flight = free_flight(media, 0, o, d, t_max, u, tracking_key(seed, i, 0, 2))
    if flight.scattered:
        scattered[i] = flight.weight
    else:
        passed[i] = flight.weight


@wp.kernel
def glow(media: MediumData, o: wp.vec3, d: wp.vec3, t_max: float, seed: int, emitted: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    u = (float(i) + 0.5) / float(emitted.shape[0])
    emitted[i] = free_flight(media, 0, o, d, t_max, u, tracking_key(seed, i, 0, 2)).emitted


RAY_O = np.array([-2.0, 0.3, 0.2])
RAY_D = np.array([1.0, 0.15, -0.1]) / np.linalg.norm([1.0, 0.15, -0.1])
T_MAX = 5.0


def quadrature(n=200_000, texels=TEXELS, ray_o=None, ray_d=None):
    """float64 ``(T, S, crosses, E)`` along the ray: the transmittance exp(-int sigma_t), the single
    scattering integral int T(t) sigma_s(t) dt and the emission int T(t) GLOW(t) dt, by the
    midpoint rule (the medium is clear outside its grid's box)."""
    ray_o, ray_d = (RAY_O, RAY_D) if ray_o is None else (ray_o, ray_d)
    t = (np.arange(n) + 0.5) * (T_MAX / n)
    p = ray_o + t[:, None] * ray_d
    local = (np.linalg.inv(TO_WORLD) @ np.c_[p, np.ones(n)].T).T[:, :3]
    inside = np.all((local >= 0) & (local <= 1), axis=1)[:, None]
    sigma_t = np.where(inside, SCALE * trilinear(texels, TO_WORLD, p), 0.0)
    sigma_s = sigma_t * trilinear(ALBEDO, TO_WORLD, p)
    optical = np.cumsum(sigma_t, axis=0) * (T_MAX / n)
    emitted = np.sum(np.exp(-optical) * np.where(inside, trilinear(GLOW, TO_WORLD, p), 0.0), axis=0) * (T_MAX / n)
    return np.exp(-optical[-1]), np.sum(np.exp(-optical) * sigma_s, axis=0) * (T_MAX / n), inside.any(), emitted


def test_the_lookup_is_trilinear_between_texel_centres_and_clamped():
    media = medium_table()
    points = RNG.uniform(-3.0, 3.0, size=(4000, 3))  # inside the box and far outside it
    out = wp.zeros(len(points), dtype=wp.vec3)
    wp.launch(lookup, dim=len(points), inputs=[media, 0, wp.array(points.astype(np.float32), dtype=wp.vec3), out])
    expected = SCALE * trilinear(TEXELS, TO_WORLD, points)
    np.testing.assert_allclose(out.numpy(), expected, rtol=1e-4, atol=1e-4)


def test_the_lookup_matches_mitsubas_gridvolume(tmp_path):
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    from wrt.volumes import write_vol

    write_vol(tmp_path / "g.vol", TEXELS)
    grid = mi.load_dict(
        {"type": "gridvolume", "filename": str(tmp_path / "g.vol"), "to_world": mi.ScalarTransform4f(TO_WORLD)}
    )
    media = medium_table(scale=1.0)
    points = RNG.uniform(-2.0, 2.0, size=(300, 3))
    out = wp.zeros(len(points), dtype=wp.vec3)
    wp.launch(lookup, dim=len(points), inputs=[media, 0, wp.array(points.astype(np.float32), dtype=wp.vec3), out])
    theirs = []
    for p in points:
        it = mi.Interaction3f()
        it.p = mi.Point3f(*p)
        theirs.append(list(grid.eval(it)))
    np.testing.assert_allclose(out.numpy(), np.array(theirs), rtol=1e-4, atol=1e-5)


SPARSE = np.zeros((12, 16, 20, 3), np.float32)  # clear but for a chromatic slab two thirds along x
SPARSE[4:8, 6:10, 12:15] = RNG.uniform(0.05, 0.3, size=(4, 4, 3, 3))
SPARSE[6, 8, 13] = (2.0, 1.0, 3.0)
ACROSS_O = (TO_WORLD @ [-0.1, 0.5, 0.5, 1.0])[:3]  # a ray along the grid's x axis, through its middle
ACROSS_D = TO_WORLD[:3, 0] / np.linalg.norm(TO_WORLD[:3, 0])


@pytest.mark.parametrize(
    "seed, texels, ray",
    [(1, TEXELS, None), (2, TEXELS, None), (3, SPARSE, (ACROSS_O, ACROSS_D))],
    ids=["dense-1", "dense-2", "sparse"],
)
def test_delta_and_ratio_tracking_are_unbiased_against_a_float64_quadrature(seed, texels, ray):
    """Ratio tracking's mean is T per channel; delta tracking's weight past the segment averages
    to T and at a collision to the single-scattering integral, per channel of a chromatic grid:
    one dense everywhere, and a sparse one, clear but for a slab across the ray, whose majorant
    grid holds cells of 0 before and after the slab's (a walk that lost its cell would miss it)."""
    ray_o, ray_d = (RAY_O, RAY_D) if ray is None else ray
    expected_t, expected_s, crosses, _ = quadrature(texels=texels, ray_o=ray_o, ray_d=ray_d)
    assert crosses and 0.02 < expected_t.min() and expected_t.max() < 0.9  # the ray is attenuated, not opaque
    n = 200_000
    media = medium_table(sigma_t=texels)
    transmitted, passed, scattered = (wp.zeros(n, dtype=wp.vec3) for _ in range(3))
    wp.launch(
        track,
        dim=n,
        inputs=[media, wp.vec3(*ray_o), wp.vec3(*ray_d), T_MAX, seed, transmitted, passed, scattered],
    )
    for samples, expected in (
        (transmitted.numpy(), expected_t),
        (passed.numpy(), expected_t),
        (scattered.numpy(), expected_s),
    ):
        mean = samples.mean(axis=0)
        error = samples.std(axis=0) / math.sqrt(n)
        assert np.all(np.abs(mean - expected) < 4 * error + 1e-6), (mean, expected, error)


def test_a_grid_of_zero_majorant_is_clear():
    media = medium_table(sigma_t=np.zeros_like(TEXELS))
    n = 64
    transmitted, passed, scattered = (wp.zeros(n, dtype=wp.vec3) for _ in range(3))
    wp.launch(track, dim=n, inputs=[media, wp.vec3(*RAY_O), wp.vec3(*RAY_D), T_MAX, 1, transmitted, passed, scattered])
    np.testing.assert_array_equal(transmitted.numpy(), 1.0)
    np.testing.assert_array_equal(passed.numpy(), 1.0)
    np.testing.assert_array_equal(scattered.numpy(), 0.0)


@pytest.mark.parametrize("sigma_n", [0.0, 3.0])
def test_emission_scored_at_every_collision_is_unbiased(sigma_n):
    """A glowing grid's emission, scored at each tentative collision as the throughput so far times
    ``emission / sigma_bar``, averages to the float64 ``int T(t) emission(t) dt``, per channel,
    whatever null density ``sigma_n`` adds to the bound."""
    *_, expected = quadrature()
    n = 200_000
    emitted = wp.zeros(n, dtype=wp.vec3)
    media = medium_table(emission=GLOW, sigma_n=sigma_n)
    wp.launch(glow, dim=n, inputs=[media, wp.vec3(*RAY_O), wp.vec3(*RAY_D), T_MAX, 3, emitted])
    samples = emitted.numpy().astype(np.float64)
    mean, error = samples.mean(axis=0), samples.std(axis=0) / math.sqrt(n)
    assert np.all(np.abs(mean - expected) < 4 * error), (mean, expected, error)
    assert np.all(error < 0.01 * expected)  # a test with teeth: 4 errors are 4% at most


def test_a_clear_glowing_grid_is_tracked_and_emits_along_its_chord():
    """A grid of zero extinction that glows gets a bound of its own (``wrt.bake.GLOW_COLLISIONS``
    collisions along its box's shortest edge) and emits its constant radiance times the chord."""
    media = medium_table(sigma_t=np.zeros_like(TEXELS), emission=np.full((1, 1, 1, 3), 0.5, np.float32))
    n = 20_000
    emitted = wp.zeros(n, dtype=wp.vec3)
    wp.launch(glow, dim=n, inputs=[media, wp.vec3(*RAY_O), wp.vec3(*RAY_D), T_MAX, 5, emitted])
    t = (np.arange(100_000) + 0.5) * (T_MAX / 100_000)
    local = (np.linalg.inv(TO_WORLD) @ np.c_[RAY_O + t[:, None] * RAY_D, np.ones(len(t))].T).T[:, :3]
    chord = np.all((local >= 0) & (local <= 1), axis=1).sum() * (T_MAX / len(t))
    samples = emitted.numpy().astype(np.float64)
    mean, error = samples.mean(axis=0), samples.std(axis=0) / math.sqrt(n)
    assert chord > 0.3 and np.all(np.abs(mean - 0.5 * chord) < 4 * error + 1e-3 * chord), (mean, chord)


@pytest.mark.parametrize("texels", [TEXELS, SPARSE], ids=["dense", "sparse"])
def test_the_majorant_grid_bounds_every_lookup_in_its_cell(texels):
    """No trilinear extinction inside a majorant cell exceeds the cell's bound (float64 lookups at
    random points of the unit cube, ``sigma_n`` added to every cell), and the grid is coarse: at
    most 8 cells a side."""
    medium = Medium(name="m", type="heterogeneous", sigma_t=Volume(values=texels, to_world=np.eye(4)), sigma_n=0.25)
    bounds = _majorant_grid(medium, (np.eye(4), texels * np.float32(SCALE)))
    assert bounds.shape == tuple(min(r, 8) for r in texels.shape[:3])
    q = RNG.uniform(0.0, 1.0, size=(100_000, 3))
    values = SCALE * trilinear(texels, np.eye(4), q).max(axis=1) + 0.25
    cell = np.minimum((q * np.array(bounds.shape[::-1])).astype(int), np.array(bounds.shape[::-1]) - 1)
    assert np.all(values <= bounds[cell[:, 2], cell[:, 1], cell[:, 0]] * (1 + 1e-6))
    if texels is SPARSE:
        assert bounds.min() == 0.25 and bounds.max() == pytest.approx(3.0 * SCALE + 0.25)
