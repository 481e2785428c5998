"""Plain-text tables for the command line: columns padded to their widest cell."""

from __future__ import annotations


def text_table(rows: list[list[str]], right: frozenset[int] | set[int] = frozenset(), rule: bool = False) -> str:
    """``rows`` (the first is the header) as aligned text: columns two spaces apart, left-aligned
    except the column indices in ``right``; ``rule`` adds a line of dashes under the header."""
    widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]))]
    lines = [
        "  ".join(
            cell.rjust(w) if k in right else cell.ljust(w) for k, (cell, w) in enumerate(zip(row, widths))
        ).rstrip()
        for row in rows
    ]
    if rule:
        lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
