"""Export of a recorded run as CSV files in SI units."""
from __future__ import annotations

import contextlib
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..outputs import replaced_file
from .samples import ARRAYS, BRAKE_COMMAND, STOPS, plant_samples

if TYPE_CHECKING:
    from .report import RunReport

__all__ = ["write_csv", "FILES"]

#: The file of each exported series.
FILES = {"vehicles/speed": "speed_m_s.csv", "vehicles/position": "position_m.csv",
         "vehicles/brake_force": "brake_force_N.csv",
         "vehicles/traction_force": "traction_force_N.csv",
         "couplers/force": "coupler_force_N.csv", BRAKE_COMMAND: "brake_command.csv",
         "coupler_peaks": "coupler_peaks.csv", STOPS: "stops.csv",
         "vehicles/brake_pipe_pressure": "brake_pipe_pressure_Pa.csv",
         "vehicles/brake_cylinder_pressure": "brake_cylinder_pressure_Pa.csv",
         "vehicles/block_temperature": "block_temperature_K.csv",
         "vehicles/wheel_temperature": "wheel_temperature_K.csv"}


def write_csv(report: RunReport, outdir) -> list[Path]:
    """Export the recorded arrays and the per-coupler peaks as CSV (SI units).

    One file per array topic (``speed_m_s.csv``, ``position_m.csv``, ``brake_force_N.csv``,
    ``traction_force_N.csv``, ``coupler_force_N.csv``; with a brake pipe also
    ``brake_pipe_pressure_Pa.csv`` and ``brake_cylinder_pressure_Pa.csv``, gauge: a ``time_s``
    column, then one column per vehicle ``vehicle_0`` (head) ... or coupler ``coupler_1``
    (behind the head) ...), ``brake_command.csv``, ``coupler_peaks.csv`` and, for a recording
    with the plant's stops, ``stops.csv`` (one row a stop, the columns of
    :attr:`~.report.RunReport.stops`, a criterion's status as ``verdict_<name>``). The recording is
    streamed again, with the report's checks (:mod:`.samples`): every sample is written, or
    none of the files.

    Parameters
    ----------
    report : RunReport
    outdir : str or path-like

    Returns
    -------
    list of pathlib.Path

    Raises
    ------
    BagError
        The recording holds what the plant never publishes.
    OSError
        A file cannot be written (named; no half-written file is left).
    """
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    handles: dict = {}
    blocks: dict = {}

    def flush(name):
        rows = blocks.pop(name, None)
        if rows:
            np.savetxt(handles[name], np.array(rows), delimiter=",", fmt="%.10g")

    with contextlib.ExitStack() as files:
        def create(name, header):
            handles[name] = files.enter_context(replaced_file(out / FILES[name]))
            handles[name].write(header + "\n")

        create(BRAKE_COMMAND, "time_s,emergency")
        for name, t, log_ns, value in plant_samples(report.source, report.namespace, report.stamped):
            if name == BRAKE_COMMAND:
                handles[name].write(f"{log_ns * 1e-9:.9f},{int(value)}\n")
                continue
            if name == STOPS:  # the report's records of them, below
                continue
            if name not in handles:
                first = 1 if ARRAYS[name] == "coupler" else 0
                create(name, ",".join(["time_s"] + [f"{ARRAYS[name]}_{i + first}"
                                                    for i in range(value.size)]))
            rows = blocks.setdefault(name, [])
            rows.append(np.concatenate(([t], value)))
            if len(rows) >= 1000:
                flush(name)
        for name in list(blocks):
            flush(name)
        create("coupler_peaks", "coupler,peak_draft_N,peak_draft_time_s,peak_buff_N,"
                                "peak_buff_time_s")
        table = np.column_stack((np.arange(1, report.n_couplers + 1),
                                 report.coupler_peak_draft_N, report.coupler_peak_draft_time_s,
                                 report.coupler_peak_buff_N, report.coupler_peak_buff_time_s))
        np.savetxt(handles["coupler_peaks"], table, delimiter=",", fmt=["%d"] + ["%.10g"] * 4)
        if report.stops:
            _write_stops(report.stops, create, handles)
    return [out / FILES[name] for name in handles]


def _write_stops(stops: list, create, handles) -> None:
    """``stops.csv``: one row a recorded stop (empty cells: not reached)."""
    import csv

    criteria = sorted({name for s in stops for name in s["criteria"]})
    columns = [k for k in stops[0] if k != "criteria"]
    create(STOPS, ",".join(columns + [f"verdict_{c}" for c in criteria]))
    writer = csv.writer(handles[STOPS], lineterminator="\n")
    for s in stops:
        writer.writerow(["" if s[k] is None else s[k] for k in columns]
                        + [s["criteria"].get(c, "") for c in criteria])
