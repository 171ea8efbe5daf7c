"""Short displays of the public objects: a one-line ``repr`` and a small HTML table for
notebooks (``_repr_html_``), both a screen at most whatever the train's length. Imports
nothing of the package (every layer may use it)."""
from __future__ import annotations

import math
from html import escape

#: Longest text of one cell [characters].
CELL = 120


def number(x, fmt: str = ".4g") -> str:
    """A number as text; ``n/a`` for None or NaN."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return format(x, fmt) if isinstance(x, (int, float)) and not isinstance(x, bool) else \
        str(x)


def html_table(title: str, rows, head=None) -> str:
    """A titled table; every cell is escaped text (never markup) and cut to :data:`CELL`."""
    def cut(v) -> str:
        text = str(v)
        return escape(text if len(text) <= CELL else text[: CELL - 1] + "…")

    head_html = "" if head is None else \
        "<tr>" + "".join(f"<th>{cut(h)}</th>" for h in head) + "</tr>"
    body = "".join("<tr>" + "".join(f"<td style=\"text-align:left\">{cut(c)}</td>"
                                    for c in row) + "</tr>" for row in rows)
    return f"<div><b>{escape(title)}</b><table>{head_html}{body}</table></div>"


def groups(names) -> list[tuple[str, int]]:
    """Runs of equal names: ``["a", "a", "b"]`` -> ``[("a", 2), ("b", 1)]``."""
    out: list[list] = []
    for name in names:
        if out and out[-1][0] == name:
            out[-1][1] += 1
        else:
            out.append([name, 1])
    return [(n, k) for n, k in out]
