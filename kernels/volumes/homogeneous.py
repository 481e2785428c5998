"""``homogeneous``: a medium of constant extinction ``sigma_t`` and albedo, Mitsuba 3's
``homogeneous`` (pbrt-v4's ``HomogeneousMedium``).

Free flight is sampled exactly (the medium is its own majorant, so every collision is real) by
the channel-mixture rule of spectral MIS: a channel ``c`` chosen uniformly with each segment's
sample, a distance ``t`` drawn with density ``sigma_t[c] exp(-sigma_t[c] t)``, and the weight
divided by the density averaged over the three channels (the balance heuristic over the
channels, as Mitsuba 3's ``volpathmis`` weighs them). A chromatic medium thus costs no channel
its samples, and a grey one reduces to the classic estimator: weight ``albedo`` at a collision,
1 past the segment. Transmittance along a shadow ray is the closed form ``exp(-sigma_t d)``.
An emissive medium's radiance along the segment is its closed form,
``emission (1 - exp(-sigma_t d)) / sigma_t`` (``emission d`` where clear): every sample has it
exactly, where Mitsuba 3 scores it at the tracking's collisions (the same image, less noise).

References
----------
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. 11.2 and 14.1 (free-flight sampling).
W. Jakob et al., Mitsuba 3, ``src/media/homogeneous.cpp``, ``src/integrators/volpathmis.cpp``.
"""

import warp as wp

from ..sampling import ONE_MINUS_EPSILON
from .data import FreeFlight
from .interface import MediumType

TYPE = MediumType("homogeneous", ("sigma_t", "albedo", "scale", "emission"))


@wp.func
def homogeneous_transmittance(sigma_t: wp.vec3, distance: float) -> wp.vec3:
    """``exp(-sigma_t distance)`` per channel; a clear channel (0) transmits 1 even over an
    infinite distance."""
    out = wp.vec3(1.0)
    for k in range(3):
        if sigma_t[k] > 0.0:
            out[k] = wp.exp(-sigma_t[k] * distance)
    return out


@wp.func
def homogeneous_emitted(sigma_t: wp.vec3, emission: wp.vec3, distance: float) -> wp.vec3:
    """The radiance ``emission`` (per unit length) emits along ``distance`` towards its start:
    ``emission (1 - exp(-sigma_t distance)) / sigma_t`` per channel, ``emission distance`` where
    clear. Below an optical depth ``x`` of 1/64 the difference ``1 - exp(-x)`` would lose its
    digits to cancellation (in float32 1.3% off at 1e-6, 19% at 1e-7): its series ``x (1 - x/2 +
    x^2/6 - x^3/24)`` is taken there, exact to 1e-9."""
    out = wp.vec3(0.0)
    for k in range(3):
        if emission[k] > 0.0:
            x = wp.where(sigma_t[k] > 0.0, sigma_t[k] * distance, 0.0)  # clear: 0, even over an infinite distance
            if x < 0.015625:
                out[k] = emission[k] * distance * (1.0 - x * (0.5 - x * (1.0 / 6.0 - x / 24.0)))
            else:
                out[k] = emission[k] * (1.0 - wp.exp(-x)) / sigma_t[k]
    return out


@wp.func
def homogeneous_free_flight(sigma_t: wp.vec3, albedo: wp.vec3, emission: wp.vec3, t_max: float, u: float) -> FreeFlight:
    """A free-flight sample over ``0 < t < t_max`` (``t_max`` may be infinite) from one uniform
    number ``u``: its first third picks the channel, the rest the distance; ``emitted`` is the
    radiance emitted along the whole segment (its closed form)."""
    x = u * 3.0
    channel = wp.min(int(x), 2)
    u1 = wp.min(x - float(channel), ONE_MINUS_EPSILON)
    flight = FreeFlight()
    flight.scattered = False
    flight.t = t_max
    flight.weight = wp.vec3(0.0)
    flight.emitted = homogeneous_emitted(sigma_t, emission, t_max)
    if sigma_t[channel] > 0.0:
        t = -wp.log(1.0 - u1) / sigma_t[channel]
        if t < t_max:
            flight.scattered = True
            flight.t = t
    tr = homogeneous_transmittance(sigma_t, flight.t)
    if flight.scattered:
        pdf = (sigma_t[0] * tr[0] + sigma_t[1] * tr[1] + sigma_t[2] * tr[2]) / 3.0
        if pdf > 0.0:
            flight.weight = wp.cw_mul(tr, wp.cw_mul(sigma_t, albedo)) / pdf
    else:
        passed = (tr[0] + tr[1] + tr[2]) / 3.0  # the probability of passing, averaged
        if passed > 0.0:
            flight.weight = tr / passed
    return flight
