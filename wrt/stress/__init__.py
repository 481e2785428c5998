"""The numerical stress suite behind ``wrt stress``: adversarial rays through the real Warp kernels.

Every case builds its scene in memory, shoots rays through the kernels the renderer uses
(``wrt.kernels.traverse.trace_closest`` / ``trace_any``, ``wrt.kernels.stress.trace_spawned``, or
``wrt.render`` with the raycast and whitted integrators) and counts the rays that break the
case's rule. A case passes when that count is zero. The bounds and what each case measures are
documented in ``docs/stress.md``. The cases are grouped by theme: ``watertight``, ``offsets``
(self-intersection), ``precision`` (against float64), ``degenerate`` (grazing and degenerate
geometry), ``refraction`` (and whole images); ``common`` builds their scenes, ``report`` their table.

Ray budget: ``rays`` (N, ``wrt stress --rays``) is the number of rays each ray-batch case
shoots; the image cases render fixed small images whatever N (their ray count is reported).
"""

from .report import CaseResult, format_table
from .suite import CASES, DEFAULT_RAYS, command, run_suite

__all__ = ["CASES", "DEFAULT_RAYS", "CaseResult", "command", "format_table", "run_suite"]
