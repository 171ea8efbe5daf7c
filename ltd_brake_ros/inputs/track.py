"""Track files: gradient and curve profile along the line (YAML or CSV)."""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from .schema import (Fields, InputError, decimal_or_text, decode_text, load_yaml, read_input,
                     resolve_config_path)


@dataclass(frozen=True)
class Track:
    """Track profile: sections starting at given chainages.

    Attributes
    ----------
    chainage_m : tuple of float
        Start of each section, strictly increasing [m]; a section runs to the next start, the
        last to infinity; before the first start the first section applies.
    gradient_permille : tuple of float
        Gradient of each section, positive uphill in the direction of travel [per mille].
    radius_m : tuple of float
        Curve radius of each section, 0 on straight track [m].
    start_chainage_m : float
        Chainage of the head's front at t = 0 [m].
    source : str
        File the profile came from.

    Examples
    --------
    >>> from ltd_brake_ros import load_track
    >>> load_track().start_chainage_m  # level straight track
    0.0
    """

    chainage_m: tuple[float, ...] = (0.0,)
    gradient_permille: tuple[float, ...] = (0.0,)
    radius_m: tuple[float, ...] = (0.0,)
    start_chainage_m: float = 0.0
    source: str = "level straight track"


#: Smallest curve radius accepted [m] (Roeckl's formula holds for main-line curves).
MIN_RADIUS_M = 100.0


def load_track(path: str | os.PathLike, start_chainage_m: float | None = None) -> Track:
    """Load a track profile from YAML or CSV.

    YAML: ``start_chainage_m`` (optional) and ``sections``, a list of mappings with
    ``from_m``, ``gradient_permille`` (default 0) and ``radius_m`` (default 0 = straight).
    CSV: a header ``chainage_m,gradient_permille,radius_m`` and one row per section.

    Parameters
    ----------
    path : str or path-like
    start_chainage_m : float, optional
        Overrides the file's start chainage of the head [m].

    Returns
    -------
    Track
    """
    p = resolve_config_path(path)
    rows: list[tuple[float, float, float]] = []
    start = 0.0
    if p.suffix.lower() == ".csv":
        import csv

        import io

        text = decode_text(read_input(p), p)
        with io.StringIO(text, newline="") as fh:
            reader = csv.DictReader(fh)
            need = {"chainage_m", "gradient_permille"}
            if not reader.fieldnames or not need <= set(reader.fieldnames):
                raise InputError(p, "header", "needs columns chainage_m, gradient_permille "
                                 "and optionally radius_m")
            for i, row in enumerate(reader):
                f = Fields({k: _csv_number(v) for k, v in row.items() if k}, str(p), f"row {i + 2}")
                rows.append((f.number("chainage_m"), f.number("gradient_permille", lo=-100, hi=100),
                             f.number("radius_m", 0.0, lo=0.0)))
    else:
        top = Fields(load_yaml(p), str(p))
        top.reject_unknown({"name", "description", "start_chainage_m", "sections"})
        start = top.number("start_chainage_m", 0.0)
        sections = top.data.get("sections")
        if not isinstance(sections, list) or not sections:
            raise top.error("sections", "missing or empty: give a list of sections with from_m")
        for i, sec in enumerate(sections):
            f = Fields(sec, str(p), f"sections[{i}]")
            f.reject_unknown({"from_m", "gradient_permille", "radius_m"})
            rows.append((f.number("from_m"), f.number("gradient_permille", 0.0, lo=-100, hi=100),
                         f.number("radius_m", 0.0, lo=0.0)))
    if not rows:
        raise InputError(p, "", "has no sections")
    for i, (ch, _g, r) in enumerate(rows):
        if i and not ch > rows[i - 1][0]:
            raise InputError(p, f"sections[{i}]", f"chainage {ch:g} m is not after {rows[i - 1][0]:g} m")
        if 0.0 < r < MIN_RADIUS_M:
            raise InputError(p, f"sections[{i}].radius_m",
                             f"{r:g} m is below {MIN_RADIUS_M:g} m (0 means straight)")
    if start_chainage_m is not None:
        start = float(start_chainage_m)
    return Track(tuple(r[0] for r in rows), tuple(r[1] for r in rows), tuple(r[2] for r in rows),
                 start, str(p))


def _csv_number(text: str | None) -> Any:
    if text is None or text.strip() == "":
        return None
    return decimal_or_text(text)
