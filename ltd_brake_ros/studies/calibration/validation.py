"""The validation targets of Tables 1-2 (``ltd-brake validate``)."""
from __future__ import annotations

import numpy as np

from .forces import BUFF_TOL, DISTANCE_TOL, DRAFT_TOL, POSITION_TOL


def validation_targets(rows) -> list[tuple[str, bool, str]]:
    """The in-train force and distance targets against Tables 1-2, checked on validation rows.

    Parameters
    ----------
    rows : list of ValidationRow

    Returns
    -------
    list of (str, bool, str)
        Criterion, met, and the worst case in words; criteria without a row to check are left
        out.
    """
    out = []

    def worst(values, label, digits=1):
        k = int(np.argmax([abs(v) for v, _ in values]))
        return f"worst {values[k][0]:+.{digits}f}{label} (run {values[k][1]})"

    draft = [(100 * (r.result.peak_draft_kN - r.scenario.paper["draft_kN"])
              / r.scenario.paper["draft_kN"], r.scenario.number) for r in rows]
    buff = [(100 * (-r.result.peak_buff_kN - r.scenario.paper["buff_kN"])
             / r.scenario.paper["buff_kN"], r.scenario.number) for r in rows]
    pos = [(r.result.peak_draft_coupler - r.scenario.paper["draft_coupler"], r.scenario.number)
           for r in rows] + [(r.result.peak_buff_coupler - r.scenario.paper["buff_coupler"],
                              r.scenario.number) for r in rows]
    if rows:
        out.append((f"peak draft within +/-{100 * DRAFT_TOL:g} % of the paper",
                    all(abs(v) <= 100 * DRAFT_TOL for v, _ in draft), worst(draft, " %")))
        out.append((f"peak buff within +/-{100 * BUFF_TOL:g} % of the paper",
                    all(abs(v) <= 100 * BUFF_TOL for v, _ in buff), worst(buff, " %")))
        out.append((f"peak positions within +/-{POSITION_TOL} couplers of the paper",
                    all(abs(v) <= POSITION_TOL for v, _ in pos), worst(pos, " couplers")))
    for speed, tol in sorted(DISTANCE_TOL.items(), reverse=True):
        dist = [(r.distance_error_percent, r.scenario.number) for r in rows
                if r.scenario.speed_kmh == speed]
        if dist:
            out.append((f"stopping distance within +/-{100 * tol:g} % of LTDPoliTo at "
                        f"{speed:g} km/h", all(abs(v) <= 100 * tol for v, _ in dist),
                        worst(dist, " %", 2)))
    return out
