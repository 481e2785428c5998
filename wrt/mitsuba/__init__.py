"""Mitsuba 3 scene XML -> a wrt scene document (the dict that ``wrt.loader.parse_scene`` validates).

`load_mitsuba` converts the common subset of Mitsuba 3's scene XML: ``perspective`` and
``thinlens`` sensors, ``hdrfilm`` with its reconstruction filter, the ``independent`` and
``stratified`` samplers, the ``path`` integrator, the shapes ``sphere``, ``rectangle``, ``cube``,
``obj`` and ``ply`` with their ``to_world`` transforms, the BSDFs ``diffuse``, ``conductor``,
``roughconductor``, ``dielectric`` and ``twosided``, and the emitters ``area``, ``point``,
``spot``, ``constant`` and ``directional``. ``<include>``, ``<path>``, ``<default>``
parameters with ``$name`` substitution and ``<ref id=...>`` references work as in Mitsuba. The mapping of every element
and parameter, the conventions that differ, and every warning are listed in ``docs/mitsuba.md``.

Faithful or refused: whatever would make wrt render the converted scene differently from Mitsuba
in expectation (an unsupported element or parameter, a BSDF replaced by its closest match) is a
`WrtError` naming the file, the line and the element, or with ``approximate=True`` converted
anyway and reported, once per cause. Parameters that change only noise (sampler type,
seed, Russian roulette depth) or the output file (pixel and file formats) convert silently.

Frames and units are Mitsuba's and wrt's alike: right-handed world space, angles in degrees,
linear RGB; radiance in W/(m^2 sr), intensity in W/sr, irradiance in W/m^2.

Reading the file (``xml``: elements, parameters, references, transforms, warnings) is apart
from converting it: ``sensors`` (sensor, film, filter, sampler, integrator), ``bsdfs``,
``shapes`` and ``emitters``, one module per plugin kind; ``scene`` puts them together.
"""

from .bsdfs import IOR_TABLE
from .scene import load_mitsuba
from .sensors import FILTERS, MAX_DEPTH, SAMPLERS
from .transforms import look_at_matrix, rotation_matrix, vertical_fov

__all__ = [
    "FILTERS",
    "IOR_TABLE",
    "MAX_DEPTH",
    "SAMPLERS",
    "load_mitsuba",
    "look_at_matrix",
    "rotation_matrix",
    "vertical_fov",
]
