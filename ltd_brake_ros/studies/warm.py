"""The trains whose kernels a study compiles before its worker processes start.

A study's workers would each compile the kernels they lack, silently and all at once; the
study's own process compiles them first instead, announced with their estimated duration
(:func:`~ltd_brake_ros.first_run.compile_here`), so that the workers load them.
"""
from __future__ import annotations

from typing import Iterator

__all__ = ["CAMPAIGN_DRAWS", "campaign_runs"]

#: Runs of a campaign whose trains are looked at for the kinds of kernels it needs (a kind met
#: only later is compiled by the worker that meets it).
CAMPAIGN_DRAWS = 32


def campaign_runs(c, draws: int = CAMPAIGN_DRAWS) -> Iterator[dict]:
    """Simulator arguments of a campaign's first trains, one per kind of kernels.

    Parameters
    ----------
    c : Campaign
    draws : int, optional
        Runs looked at (the first ones).

    Yields
    ------
    dict
        Arguments of :class:`~ltd_brake_ros.simulator.Simulator` (a train that cannot be drawn
        is left to its run, which reports it).
    """
    from ..inputs import consist_from_mapping
    from ..compiled import compile_kind
    from .campaign import draw, models

    seen = set()
    for run_id in range(min(c.runs, draws)):
        try:
            sample, data = draw(c, run_id)
            consist = consist_from_mapping(data, f"{c.source} run {run_id}")
            params, lut = models(c, sample)
        except Exception:  # noqa: BLE001 - the run itself reports what is wrong with it
            continue
        kind = compile_kind(consist, params)
        if kind not in seen:
            seen.add(kind)
            speed = min(sample["speed_kmh"].values(), default=50.0)
            yield dict(consist=consist, speed_kmh=speed, params=params, lut=lut,
                       step_s=c.step_s)
