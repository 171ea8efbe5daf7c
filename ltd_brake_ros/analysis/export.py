"""Export of a recorded run as CSV files in SI units."""
from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..recording.cdr import decode_bool, decode_float64_array
from ..recording.reader import TruncatedBagWarning, read_bag

if TYPE_CHECKING:
    from .report import RunReport

__all__ = ["write_csv"]


def write_csv(report: RunReport, outdir) -> list[Path]:
    """Export the recorded arrays and the per-coupler peaks as CSV (SI units).

    One file per array topic (``speed_m_s.csv``, ``position_m.csv``, ``brake_force_N.csv``,
    ``traction_force_N.csv``, ``coupler_force_N.csv``: a ``time_s`` column, then one column
    per vehicle ``vehicle_0`` (head) ... or coupler ``coupler_1`` (behind the head) ...),
    ``brake_command.csv`` and ``coupler_peaks.csv``. The recording is streamed again.

    Parameters
    ----------
    report : RunReport
    outdir : str or path-like

    Returns
    -------
    list of pathlib.Path
    """
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    ns = report.namespace
    files = {f"{ns}/vehicles/speed": ("speed_m_s.csv", "vehicle", 0),
             f"{ns}/vehicles/position": ("position_m.csv", "vehicle", 0),
             f"{ns}/vehicles/brake_force": ("brake_force_N.csv", "vehicle", 0),
             f"{ns}/vehicles/traction_force": ("traction_force_N.csv", "vehicle", 0),
             f"{ns}/couplers/force": ("coupler_force_N.csv", "coupler", 1)}
    handles: dict = {}
    blocks: dict = {}
    written = []

    def flush(topic):
        rows = blocks.pop(topic, None)
        if rows:
            np.savetxt(handles[topic], np.array(rows), delimiter=",", fmt="%.10g")

    try:
        cmd = open(out / "brake_command.csv", "w")  # noqa: SIM115 - closed below
        handles["__cmd"] = cmd
        cmd.write("time_s,emergency\n")
        written.append(out / "brake_command.csv")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TruncatedBagWarning)
            for topic, _type, log_time_ns, data in read_bag(report.source):
                if topic == f"{ns}/brake_command":
                    cmd.write(f"{log_time_ns * 1e-9:.9f},{int(decode_bool(data))}\n")
                    continue
                spec = files.get(topic)
                if spec is None:
                    continue
                values = decode_float64_array(data)
                if topic not in handles:
                    name, label, first = spec
                    h = handles[topic] = open(out / name, "w")  # noqa: SIM115
                    h.write(",".join(["time_s"] + [f"{label}_{i + first}"
                                                   for i in range(values.size)]) + "\n")
                    written.append(out / name)
                rows = blocks.setdefault(topic, [])
                if rows and len(rows[0]) != values.size + 1:
                    continue  # a change of train length cannot go in the same table
                rows.append(np.concatenate(([log_time_ns * 1e-9], values)))
                if len(rows) >= 1000:
                    flush(topic)
        for topic in list(blocks):
            flush(topic)
    finally:
        for h in handles.values():
            h.close()
    peaks = out / "coupler_peaks.csv"
    table = np.column_stack((np.arange(1, report.n_couplers + 1), report.coupler_peak_draft_N,
                             report.coupler_peak_draft_time_s, report.coupler_peak_buff_N,
                             report.coupler_peak_buff_time_s))
    np.savetxt(peaks, table, delimiter=",", fmt=["%d"] + ["%.10g"] * 4, comments="",
               header="coupler,peak_draft_N,peak_draft_time_s,peak_buff_N,peak_buff_time_s")
    written.append(peaks)
    return written
