"""What a medium type and a phase function type are: the description the registry
(``wrt.kernels.volumes``) derives the ``[[medium]]`` types and keys from. A medium type (one
module of this package, as a Mitsuba 3 medium plugin) names its ``type`` value and the keys it
reads; a phase function type likewise, for the
``phase = { type = ... }`` table of a medium."""

from dataclasses import dataclass


@dataclass(frozen=True)
class MediumType:
    """A ``[[medium]]`` type: ``name`` (its ``type`` value) and ``keys`` (the parameters it reads
    besides name, type and phase; ``wrt.scene.Medium``'s fields)."""

    name: str
    keys: tuple[str, ...]


@dataclass(frozen=True)
class PhaseType:
    """A phase function: ``name`` (its ``type`` value in a medium's ``phase`` table) and ``keys``
    (its parameters)."""

    name: str
    keys: tuple[str, ...]
