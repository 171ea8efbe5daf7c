"""Emergency stops at low adhesion: a scenario of Tables 1-2 on rails of constant adhesion
(0.12, 0.10, 0.07, 0.05) and of the named conditions, the wheelsets locking and sliding where
the brake asks more than the rail offers (:mod:`~ltd_brake_ros.physics.brakes.wheel_slide`).

Each stop is run with the sliding friction of locked wheelsets the condition gives (k = 0.4 of
the available adhesion, not verified) and, as the bound a sliding wheelset cannot exceed, with
k = 1 (the rail's whole adhesion, the brake force capped but never lower). The level ``low`` and
k are stated assumptions, labelled so wherever they are printed.

``python -m ltd_brake_ros.studies.low_adhesion`` prints the tables of the documentation's
wheel-slide page: scenario 6 on each condition, and :data:`TRAINS` on wet and low rails.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..inputs import get_scenario, load_consist
from ..physics.brakes import adhesion
from .runs import emergency_run

__all__ = ["CONDITIONS", "MU_LEVELS", "TRAINS", "LowAdhesionStop", "low_adhesion_stops",
           "main", "report", "trains_report"]

#: Constant adhesion levels of the study [-].
MU_LEVELS = (0.12, 0.10, 0.07, 0.05)
#: Named conditions run beside them.
CONDITIONS = ("dry", "wet", "low")
#: Trains of the second table: a scenario number or a shipped consist file, and the speed
#: [km/h]: the paper's longest train from 100 and 50 km/h, and the mixed trains.
TRAINS = ((6, 100.0), (12, 50.0), ("consists/mixed_heavy_front_light_rear.yaml", 100.0),
          ("consists/mixed_light_front_heavy_rear.yaml", 100.0))


@dataclass(frozen=True)
class LowAdhesionStop:
    """One emergency stop on a rail condition.

    Attributes
    ----------
    condition : AdhesionCondition
    distance_m, stop_time_s : float
        Stopping distance [m] and time [s], locked wheelsets sliding at k mu m g.
    distance_k1_m : float
        The stopping distance with k = 1 [m].
    vehicles_slid : int
        Vehicles whose wheels slid.
    first_slide_s : float or None
        When the first of them did [s].
    peak_draft_kN, peak_buff_kN : float
        The run's peak coupler forces (buff as a magnitude) [kN].
    """

    condition: adhesion.AdhesionCondition
    distance_m: float
    stop_time_s: float
    distance_k1_m: float
    vehicles_slid: int
    first_slide_s: float | None
    peak_draft_kN: float
    peak_buff_kN: float


def low_adhesion_stops(scenario: int = 6, conditions=None) -> list[LowAdhesionStop]:
    """The emergency stop of a scenario on each condition.

    Parameters
    ----------
    scenario : int, optional
        Scenario of Tables 1-2 (default 6: E402B + 32 Shimmns of 50 t from 100 km/h).
    conditions : iterable, optional
        Adhesion conditions (anything :func:`~ltd_brake_ros.physics.brakes.adhesion.condition`
        takes; default :data:`MU_LEVELS` then :data:`CONDITIONS`).

    Returns
    -------
    list of LowAdhesionStop
    """
    sc = get_scenario(scenario)
    rows = []
    for spec in (conditions if conditions is not None else (*MU_LEVELS, *CONDITIONS)):
        cond = adhesion.condition(spec)
        sim = emergency_run(sc.consist(), sc.speed_kmh, adhesion=cond)
        upper = emergency_run(sc.consist(), sc.speed_kmh,
                              adhesion=dataclasses.replace(cond, sliding_ratio=1.0))
        slides = sim.wheel_slides()
        peaks = sim.coupler_peaks()
        rows.append(LowAdhesionStop(
            cond, float(sim.stopping_distance_m), float(sim.stop_time_s - sim.command_time_s),
            float(upper.stopping_distance_m), len(slides),
            min((s["first_s"] for s in slides), default=None),
            peaks.draft_N / 1e3, -peaks.buff_N / 1e3))
    return rows


def report(rows: list[LowAdhesionStop], reference_m: float | None = None) -> str:
    """Markdown: the stops, with the sliding friction's and the conditions' provenance.

    Parameters
    ----------
    rows : list of LowAdhesionStop
    reference_m : float, optional
        The same stop without an adhesion condition [m] (a column of differences).

    Returns
    -------
    str
    """
    ratio = {r.condition.sliding_ratio for r in rows}
    lines = [f"sliding friction of locked wheelsets: k = "
             f"{', '.join(f'{k:g}' for k in sorted(ratio))} x mu "
             f"({adhesion.SLIDING_RATIO_SOURCE}); a locked wheelset rolls again when its "
             "brake's static friction (the kinetic law at rest) falls below k mu m g", "",
             "| adhesion | distance m | vs no cap | stop time s | distance with k = 1 m | "
             "vehicles slid, first at | peak draft / buff kN | condition's source |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        diff = "" if reference_m is None else f"{100 * (r.distance_m / reference_m - 1):+.0f} %"
        first = "none" if r.first_slide_s is None else f"{r.vehicles_slid}, {r.first_slide_s:.1f} s"
        lines.append(f"| {r.condition.name} | {r.distance_m:.1f} | {diff} | {r.stop_time_s:.1f} "
                     f"| {r.distance_k1_m:.1f} | {first} | {r.peak_draft_kN:.0f} / "
                     f"{r.peak_buff_kN:.0f} | {r.condition.source} |")
    return "\n".join(lines)


def trains_report(trains=TRAINS, conditions=("wet", "low")) -> str:
    """Markdown: each train's stop without a condition and on each of ``conditions``.

    Parameters
    ----------
    trains : iterable of (int or str, float), optional
        Scenario numbers or consist files, with the initial speed [km/h].
    conditions : iterable, optional

    Returns
    -------
    str
    """
    names = " / ".join(("off", *conditions))
    lines = [f"| train | V0 km/h | distance {names} m | peak draft {names} kN@coupler | "
             f"peak buff {names} kN@coupler | vehicles slid, longest "
             f"({' / '.join(str(c) for c in conditions)}) |",
             "|---|---|---|---|---|---|"]
    for train, speed in trains:
        consist = get_scenario(train).consist() if isinstance(train, int) else \
            load_consist(train)
        runs = [emergency_run(consist, speed, adhesion=c) for c in (None, *conditions)]
        peaks = [r.coupler_peaks() for r in runs]
        slid = []
        for r in runs[1:]:
            slides = r.wheel_slides()
            slid.append("none" if not slides else
                        f"{len(slides)}, {max(x['duration_s'] for x in slides):.1f} s")
        lines.append(
            f"| {consist.name} | {speed:g} | "
            + " / ".join(f"{r.stopping_distance_m:.1f}" for r in runs) + " | "
            + " / ".join(f"{p.draft_N / 1e3:.0f}@{p.draft_coupler}" for p in peaks) + " | "
            + " / ".join(f"{-p.buff_N / 1e3:.0f}@{p.buff_coupler}" for p in peaks) + " | "
            + " / ".join(slid) + " |")
    return "\n".join(lines)


def main() -> None:
    """Print :func:`report` for scenario 6, then :func:`trains_report`."""
    sc = get_scenario(6)
    off = emergency_run(sc.consist(), sc.speed_kmh)
    print(f"scenario 6 ({sc.consist().name}, {sc.speed_kmh:g} km/h), no adhesion cap: "
          f"{off.stopping_distance_m:.1f} m")
    print(report(low_adhesion_stops(6), off.stopping_distance_m))
    print()
    print(trains_report())


if __name__ == "__main__":
    main()
