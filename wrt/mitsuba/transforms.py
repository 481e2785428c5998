"""Mitsuba's frames in numpy: ``lookat`` and ``rotate`` matrices, field of view along an axis,
and the small helpers the plugin converters share (float64 throughout)."""

from __future__ import annotations

import math

import numpy as np

from ..errors import token


def look_at_matrix(origin, target, up) -> np.ndarray:
    """Mitsuba's ``lookat`` camera-to-world matrix: columns left, up', forward, origin.

    ``forward = normalize(target - origin)``, ``left = normalize(cross(up, forward))``,
    ``up' = cross(forward, left)``; a zero ``up`` is replaced by Mitsuba's
    ``coordinate_system(forward)`` tangent. Local +z looks at the target, local +x points to the
    left of the image.
    """
    origin, target, up = (np.asarray(v, dtype=np.float64) for v in (origin, target, up))
    forward = (target - origin) / np.linalg.norm(target - origin)
    if not np.any(up):
        up = coordinate_system(forward)
    left = np.cross(up, forward)
    left /= np.linalg.norm(left)
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = left, np.cross(forward, left), forward, origin
    return matrix


def rotation_matrix(axis, angle) -> np.ndarray:
    """4x4 right-handed rotation by ``angle`` degrees about ``axis`` (Mitsuba's ``rotate``)."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.abs(axis).max()  # first, so that the norm of a tiny or huge axis is finite and nonzero
    x, y, z = axis / np.linalg.norm(axis)
    s, c = (0.0 if abs(v) < 1e-15 else v for v in (math.sin(math.radians(angle)), math.cos(math.radians(angle))))
    matrix = np.eye(4)
    matrix[:3, :3] = [
        [x * x * (1 - c) + c, x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
        [x * y * (1 - c) + z * s, y * y * (1 - c) + c, y * z * (1 - c) - x * s],
        [x * z * (1 - c) - y * s, y * z * (1 - c) + x * s, z * z * (1 - c) + c],
    ]
    return matrix


def vertical_fov(fov: float, fov_axis: str, width: int, height: int) -> float:
    """Mitsuba's ``fov`` along ``fov_axis`` -> wrt's vertical field of view, degrees.

    ``fov_axis`` is ``x`` (Mitsuba's default), ``y``, ``diagonal``, ``smaller`` or ``larger``
    (the smaller / larger image side). With ``aspect = width / height``:
    ``tan(vfov/2) = tan(fov/2) / aspect`` for x, ``tan(fov/2) / sqrt(1 + aspect^2)`` for the
    diagonal. Raises ValueError for another axis name.
    """
    aspect = width / height
    axis = fov_axis.lower()
    if axis == "smaller":
        axis = "y" if aspect > 1 else "x"
    elif axis == "larger":
        axis = "x" if aspect > 1 else "y"
    half = math.tan(math.radians(fov) / 2)
    if axis == "x":
        half /= aspect
    elif axis == "diagonal":
        half /= math.sqrt(1.0 + aspect * aspect)
    elif axis != "y":
        raise ValueError(f"fov_axis must be x, y, diagonal, smaller or larger, got {token(fov_axis)}")
    return math.degrees(2 * math.atan(half))


def coordinate_system(n: np.ndarray) -> np.ndarray:
    """First tangent of Mitsuba's ``coordinate_system`` (Duff et al. 2017) for unit ``n``."""
    sign = math.copysign(1.0, n[2])
    a = -1.0 / (sign + n[2])
    return np.array([1.0 + sign * n[0] * n[0] * a, sign * n[0] * n[1] * a, -sign * n[0]])


def mirrors(basis: np.ndarray) -> bool:
    """Whether the 3x3 ``basis`` mirrors (negative determinant); its sign without computing the
    determinant itself, which overflows for large finite scales."""
    sign, _ = np.linalg.slogdet(basis)
    return bool(sign < 0)


def transform_point(matrix: np.ndarray, p) -> np.ndarray:
    """``p`` transformed by the 4x4 affine ``matrix``."""
    return matrix[:3, :3] @ np.asarray(p, dtype=np.float64) + matrix[:3, 3]


def as_list(v) -> list[float]:
    """A vector as a list of Python floats (what a wrt scene document holds)."""
    return [float(c) for c in v]
