"""The stress suite's results: one ``CaseResult`` per row, the table ``wrt stress`` prints, and its
JSON and Markdown report."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass, field

from ..files import report_folder, write_atomic
from ..tables import text_table


@dataclass
class CaseResult:
    """One row of the table.

    ``failures`` counts the rays (or pixels) that break the case's rule; ``worst`` is the worst
    measured error in ``unit`` (None where the rule is a count, e.g. leaks), ``bound`` the limit
    it is held to (a ray beyond it is a failure). ``detail`` holds further measured numbers.
    """

    case: str
    rays: int
    failures: int
    worst: float | None = None
    bound: float | str | None = None
    unit: str = ""
    detail: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def passed(self) -> bool:
        return self.failures == 0

    def as_dict(self) -> dict:
        return {**dataclasses.asdict(self), "passed": self.passed}


def _fmt(value, unit=""):
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    text = f"{value:.3g}" if isinstance(value, float) else str(value)
    return f"{text} {unit}".strip()


def table_rows(results: list[CaseResult]) -> list[list[str]]:
    rows = [["case", "rays", "failures", "worst error", "bound", "result"]]
    for r in results:
        rows.append(
            [
                r.case,
                str(r.rays),
                str(r.failures),
                _fmt(r.worst, r.unit),
                _fmt(r.bound, r.unit),
                "pass" if r.passed else "FAIL",
            ]
        )
    return rows


def format_table(results: list[CaseResult]) -> str:
    """The plain-text table ``wrt stress`` prints."""
    rows = table_rows(results)
    return text_table(rows, right=set(range(1, len(rows[0]))), rule=True)


def format_markdown(results: list[CaseResult], rays: int, seed: int) -> str:
    rows = table_rows(results)
    lines = [
        f"# wrt stress: N = {rays} rays, seed {seed}",
        "",
        "| " + " | ".join(rows[0]) + " |",
        "|" + "---|" * len(rows[0]),
    ]
    lines += ["| " + " | ".join(row) + " |" for row in rows[1:]]
    lines += ["", "## Details", ""]
    for r in results:
        if r.detail:
            lines.append(
                f"- **{r.case}** ({r.seconds:.1f} s): " + ", ".join(f"{k} = {_fmt(v)}" for k, v in r.detail.items())
            )
        else:
            lines.append(f"- **{r.case}** ({r.seconds:.1f} s)")
    return "\n".join(lines) + "\n"


def write_report(results: list[CaseResult], folder: str, rays: int, seed: int) -> tuple[str, str]:
    """Write ``stress.json`` and ``stress.md`` as the report folder ``folder``
    (``wrt.files.report_folder``: it replaces only an earlier report); returns their paths."""
    doc = {
        "rays": rays,
        "seed": seed,
        "passed": all(r.passed for r in results),
        "cases": [r.as_dict() for r in results],
    }
    with report_folder(folder, "wrt stress") as work:
        write_atomic(os.path.join(work, "stress.json"), json.dumps(doc, indent=2, default=float) + "\n")
        write_atomic(os.path.join(work, "stress.md"), format_markdown(results, rays, seed))
    return os.path.join(folder, "stress.json"), os.path.join(folder, "stress.md")
