"""``heterogeneous``: a medium whose extinction and albedo are volumes (Mitsuba 3's
``heterogeneous`` with ``gridvolume`` and ``constvolume`` data), tracked against a majorant.

A volume (``MediumData.volume_*`` rows) is a grid of ``res`` linear-RGB texels over the unit cube
of its own frame (``to_local``: world to that cube); a constant volume is a grid of one texel.
Lookups are trilinear between texel centres ``(i + 0.5) / res``, clamped at the faces (Mitsuba 3's
``gridvolume`` with its default ``filter_type = "bilinear"`` and ``wrap_mode = "clamp"``). The
medium is where its extinction volume's box is: a ray is tracked only over the part of its segment
inside that box (``volume_span``), and is clear elsewhere (Mitsuba 3's ``Medium::intersect_aabb``).

Tracking uses a coarse grid of grey majorants per medium (``MediumData.majorant_*``, at most
``MAX_CELLS`` cells a side over the extinction's unit cube, each the largest texel, ``scale``
applied, whose trilinear reach overlaps the cell, so no lookup in the cell exceeds it; pbrt-v4's
``MajorantGrid``). A ray walks the cells it crosses (``Walk``, a 3D DDA), and tentative collisions
come where the majorants' optical depth along it reaches ``-ln(1 - u)``; ``sigma_bar`` below is the
majorant of the collision's cell. A sparse grid is thus tracked at its local density, and clear
cells cost one step each:

- free flight (``grid_free_flight``) by delta tracking, chromatic by spectral tracking with
  average-channel probabilities (Kutz et al. 2017): a collision at ``x`` is real with probability
  ``P = mean(sigma_t(x)) / sigma_bar`` (weight ``sigma_s(x) / mean(sigma_t(x))``), else null
  (weight ``sigma_n(x) / mean(sigma_n(x))``, ``sigma_n = sigma_bar - sigma_t``). A grey medium
  has weights ``albedo`` and 1: classic delta tracking. Unbiased for every channel.
- transmittance of a shadow ray (``grid_transmittance``) by ratio tracking: the product of
  ``1 - sigma_t(x) / sigma_bar`` over the tentative collisions (Novak et al. 2014).
- emission (a ``glow`` volume): every tentative collision before the real one scores the
  throughput so far times ``emission(x) / sigma_bar`` (pbrt-v4's ``SampleT_maj`` callback, Mitsuba
  3's ``volumelight``), an unbiased estimate of ``int T(s) emission(s) ds``. ``sigma_n``, a null
  density added to the bound (Mitsuba's), makes collisions where the medium is clear.

The first distance of a free flight takes the sampler's number ``u``; every later number comes
from the counter hash of ``key`` and the step (``step_uniform``), so a path is reproducible
whatever the tiling. A segment needing more than ``MAX_STEPS`` tentative collisions is given up
(weight 0: optical depth of the majorant above about 65000 along one segment).

References
----------
J. Novak, A. Selle, W. Jarosz, "Residual ratio tracking for estimating attenuation in
participating media", ACM TOG 33(6), 2014.
P. Kutz, R. Habel, Y. K. Li, J. Novak, "Spectral and decomposition tracking for rendering
heterogeneous volumes", ACM TOG 36(4), 2017.
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. 14.2 (``SampleT_maj``).
"""

import warp as wp

from ..sampling import ONE_MINUS_EPSILON, pcg_hash, to_unit
from .data import FreeFlight, MediumData
from .interface import MediumType

TYPE = MediumType("heterogeneous", ("sigma_t", "albedo", "scale", "emission", "sigma_n"))

MAX_STEPS = wp.constant(65536)
MAX_CELLS = wp.constant(8)  # a majorant grid's cells along an axis, at most (wrt.bake.MAJORANT_CELLS)


@wp.func
def step_uniform(key: wp.uint32, step: wp.int32) -> float:
    """The ``step``-th uniform number in [0, 1) of the stream ``key``."""
    return wp.min(to_unit(pcg_hash(pcg_hash(wp.uint32(step)) ^ key)), ONE_MINUS_EPSILON)


@wp.func
def volume_lookup(media: MediumData, volume: wp.int32, p: wp.vec3) -> wp.vec3:
    """The value of ``volume`` at world point ``p``: trilinear between texel centres, clamped."""
    q = wp.transform_point(media.volume_to_local[volume], p)
    res = media.volume_res[volume]
    base = media.volume_offset[volume]
    i0 = wp.vec3i(0)
    i1 = wp.vec3i(0)
    f = wp.vec3(0.0)
    for k in range(3):
        x = wp.clamp(q[k] * float(res[k]) - 0.5, 0.0, float(res[k] - 1))
        lo = wp.min(int(wp.floor(x)), res[k] - 1)
        i0[k] = lo
        i1[k] = wp.min(lo + 1, res[k] - 1)
        f[k] = x - float(lo)
    out = wp.vec3(0.0)
    for corner in range(8):
        ix = wp.where((corner & 1) != 0, i1[0], i0[0])
        iy = wp.where((corner & 2) != 0, i1[1], i0[1])
        iz = wp.where((corner & 4) != 0, i1[2], i0[2])
        w = wp.where((corner & 1) != 0, f[0], 1.0 - f[0])
        w *= wp.where((corner & 2) != 0, f[1], 1.0 - f[1])
        w *= wp.where((corner & 4) != 0, f[2], 1.0 - f[2])
        out += w * media.volume_values[base + (iz * res[1] + iy) * res[0] + ix]
    return out


@wp.func
def volume_span(media: MediumData, volume: wp.int32, o: wp.vec3, d: wp.vec3, t_max: float) -> wp.vec2:
    """The part ``(t0, t1)`` of the ray ``o + t d``, ``0 < t < t_max``, inside ``volume``'s box
    (``t0 >= t1``: none)."""
    m = media.volume_to_local[volume]
    ol = wp.transform_point(m, o)
    dl = wp.transform_vector(m, d)
    t0 = float(0.0)
    t1 = t_max
    for k in range(3):
        if dl[k] != 0.0:
            ta = -ol[k] / dl[k]
            tb = (1.0 - ol[k]) / dl[k]
            t0 = wp.max(t0, wp.min(ta, tb))
            t1 = wp.min(t1, wp.max(ta, tb))
        elif ol[k] < 0.0 or ol[k] > 1.0:
            t1 = -1.0
    return wp.vec2(t0, t1)


@wp.func
def mean3(v: wp.vec3) -> float:
    return (v[0] + v[1] + v[2]) / 3.0


@wp.struct
class Walk:
    """A ray's walk through a medium's majorant grid, cell by cell (a 3D DDA in the grid's unit
    cube, whose ray parameter is the world one): ``t`` where it stands, ``t_end`` the end of its
    span, ``cell`` the cell it is in, ``next`` the parameter at which it leaves that cell along
    each axis and ``delta`` the parameter across one cell, ``step`` the direction of each."""

    t: float
    t_end: float
    cell: wp.vec3i
    next: wp.vec3
    delta: wp.vec3
    step: wp.vec3i


@wp.func
def walk_start(media: MediumData, medium: wp.int32, o: wp.vec3, d: wp.vec3, span: wp.vec2) -> Walk:
    """The walk of ``o + t d`` over ``span`` (inside the grid's box) from its start."""
    m = media.volume_to_local[media.density[medium]]
    ol = wp.transform_point(m, o)
    dl = wp.transform_vector(m, d)
    res = media.majorant_res[medium]
    walk = Walk()
    walk.t = span[0]
    walk.t_end = span[1]
    q = ol + span[0] * dl
    for k in range(3):
        c = wp.clamp(int(wp.floor(q[k] * float(res[k]))), 0, res[k] - 1)
        walk.cell[k] = c
        walk.next[k] = wp.inf
        walk.delta[k] = wp.inf
        walk.step[k] = 0
        if dl[k] > 0.0:
            walk.next[k] = span[0] + (float(c + 1) / float(res[k]) - q[k]) / dl[k]
            walk.delta[k] = 1.0 / (float(res[k]) * dl[k])
            walk.step[k] = 1
        elif dl[k] < 0.0:
            walk.next[k] = span[0] + (float(c) / float(res[k]) - q[k]) / dl[k]
            walk.delta[k] = -1.0 / (float(res[k]) * dl[k])
            walk.step[k] = -1
    return walk


@wp.func
def walk_bound(media: MediumData, medium: wp.int32, walk: Walk) -> float:
    """The majorant of the cell the walk is in."""
    res = media.majorant_res[medium]
    c = walk.cell
    return media.majorant_cells[media.majorant_offset[medium] + (c[2] * res[1] + c[1]) * res[0] + c[0]]


@wp.func
def walk_exit(walk: Walk) -> float:
    """Where the walk leaves its cell (or its span ends)."""
    return wp.min(wp.min(wp.min(walk.next[0], walk.next[1]), walk.next[2]), walk.t_end)


@wp.func
def walk_advance(media: MediumData, medium: wp.int32, walk: Walk) -> Walk:
    """The walk moved into the next cell along the ray (``t_end`` reached: ``t = t_end``)."""
    out = walk
    out.t = walk_exit(walk)
    axis = int(0)
    if walk.next[1] < walk.next[axis]:
        axis = 1
    if walk.next[2] < walk.next[axis]:
        axis = 2
    out.cell[axis] = walk.cell[axis] + walk.step[axis]
    out.next[axis] = walk.next[axis] + walk.delta[axis]
    res = media.majorant_res[medium]
    if out.cell[axis] < 0 or out.cell[axis] >= res[axis]:
        out.t = walk.t_end
    return out


@wp.func
def walk_collision(media: MediumData, medium: wp.int32, walk: Walk, tau: float):
    """Where the walk meets optical depth ``tau`` of the majorants: ``(the walk moved to that cell,
    the collision's t, the cell's majorant)``, ``t = t_end`` (majorant 0) where the span ends
    first."""
    out = walk
    left = tau
    for _cell in range(3 * MAX_CELLS + 3):
        if out.t >= out.t_end:
            break
        sigma_bar = walk_bound(media, medium, out)
        exit = walk_exit(out)
        depth = sigma_bar * (exit - out.t)
        if depth > left:
            return out, out.t + left / sigma_bar, sigma_bar
        left -= depth
        out = walk_advance(media, medium, out)
    return out, out.t_end, 0.0


@wp.func
def grid_free_flight(
    media: MediumData, medium: wp.int32, o: wp.vec3, d: wp.vec3, t_max: float, u: float, key: wp.uint32
) -> FreeFlight:
    """A free-flight sample along ``o + t d``, ``0 < t < t_max``, by delta tracking (above)."""
    flight = FreeFlight()
    flight.scattered = False
    flight.t = t_max
    flight.weight = wp.vec3(1.0)
    flight.emitted = wp.vec3(0.0)
    glow = media.glow[medium]
    span = volume_span(media, media.density[medium], o, d, t_max)
    if media.majorant[medium] <= 0.0 or span[0] >= span[1]:
        return flight
    walk = walk_start(media, medium, o, d, span)
    x = u
    for step in range(MAX_STEPS):
        walk, t, sigma_bar = walk_collision(media, medium, walk, -wp.log(1.0 - x))
        if sigma_bar <= 0.0:
            return flight
        walk.t = t
        p = o + t * d
        if glow >= 0:
            flight.emitted += wp.cw_mul(flight.weight, volume_lookup(media, glow, p)) / sigma_bar
        sigma_t = volume_lookup(media, media.density[medium], p)
        real = mean3(sigma_t)
        if step_uniform(key, 2 * step) * sigma_bar < real:
            sigma_s = wp.cw_mul(sigma_t, volume_lookup(media, media.tint[medium], p))
            flight.scattered = True
            flight.t = t
            flight.weight = wp.cw_mul(flight.weight, sigma_s) / real
            return flight
        sigma_n = wp.max(wp.vec3(sigma_bar) - sigma_t, wp.vec3(0.0))  # >= 0 but for rounding
        flight.weight = wp.cw_mul(flight.weight, sigma_n) / mean3(sigma_n)
        x = step_uniform(key, 2 * step + 1)
    flight.weight = wp.vec3(0.0)
    return flight


@wp.func
def grid_transmittance(
    media: MediumData, medium: wp.int32, o: wp.vec3, d: wp.vec3, distance: float, key: wp.uint32
) -> wp.vec3:
    """The transmittance along ``o + t d``, ``0 < t < distance``, by ratio tracking (above)."""
    tr = wp.vec3(1.0)
    span = volume_span(media, media.density[medium], o, d, distance)
    if media.majorant[medium] <= 0.0 or span[0] >= span[1]:
        return tr
    walk = walk_start(media, medium, o, d, span)
    for step in range(MAX_STEPS):
        walk, t, sigma_bar = walk_collision(media, medium, walk, -wp.log(1.0 - step_uniform(key, step)))
        if sigma_bar <= 0.0:
            return tr
        walk.t = t
        sigma_t = volume_lookup(media, media.density[medium], o + t * d)
        tr = wp.cw_mul(tr, wp.max(wp.vec3(1.0) - sigma_t / sigma_bar, wp.vec3(0.0)))
        if tr[0] <= 0.0 and tr[1] <= 0.0 and tr[2] <= 0.0:
            return wp.vec3(0.0)
    return wp.vec3(0.0)
