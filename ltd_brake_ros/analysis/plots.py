"""Plots of a recorded run, as PNG files (the paper's Figs. 6-7 and a coupler-force map)."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..outputs import replaced_file
from ..physics.brakes.thermal import VALIDATION
from .brake_pipe_plots import profiles_figure

if TYPE_CHECKING:
    from .report import RunReport

__all__ = ["render_markers", "write_plots"]


def write_plots(report: RunReport, outdir) -> list[Path]:
    """Write the engineer's plots as PNG files.

    ``speed.png`` (head and tail speed), ``brake_force.png`` (first wagon and tail, as the
    paper's Fig. 7), ``coupler_peaks.png`` (peak draft and buff per coupler, Fig. 6, with the
    verdicts' strength limits where the peaks come within half of them) and
    ``coupler_force_map.png`` (coupler x time, diverging colours centred at zero, draft red)
    and, when a brake pipe was recorded, ``brake_pipe.png`` (pipe pressure along the train at
    the kept instants, cylinder pressure of the head wagon and the tail in time), and when the
    brake heat was, ``brake_temperature.png`` (the hottest blocks and wheels in time).

    Parameters
    ----------
    report : RunReport
    outdir : str or path-like
        Created if needed.

    Returns
    -------
    list of pathlib.Path

    Raises
    ------
    OSError
        A file cannot be written (named; no half-written file is left).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.figure import Figure

    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    title = str(report.metadata.get("consist", {}).get("name", "")) \
        if isinstance(report.metadata.get("consist"), dict) else ""

    def save(fig, name):
        FigureCanvasAgg(fig)
        p = out / name
        with replaced_file(p, "wb") as fh:
            fig.savefig(fh, format="png", dpi=120)
        paths.append(p)

    def mark_command(ax):
        if report.command_time_s is not None:
            ax.axvline(report.command_time_s, color="0.4", ls=":", lw=1, label="emergency command")
        if report.stop_time_s is not None:
            ax.axvline(report.stop_time_s, color="0.4", ls="--", lw=1, label="stopped")

    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(report.speed_time_s, report.head_speed_m_s, label="head (vehicle 0)")
    ax.plot(report.speed_time_s, report.tail_speed_m_s, label=f"tail (vehicle "
            f"{max(report.n_vehicles - 1, 0)})", ls="--")
    mark_command(ax)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("speed [m/s]")
    sec = ax.secondary_yaxis("right", functions=(lambda v: v * 3.6, lambda v: v / 3.6))
    sec.set_ylabel("speed [km/h]")
    ax.set_title(f"Speed {title}".strip(), parse_math=False)
    ax.grid(alpha=0.3)
    ax.legend()
    save(fig, "speed.png")

    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(report.brake_time_s, report.head_wagon_brake_force_N / 1e3,
            label=f"head wagon (vehicle {report.head_wagon_index})")
    ax.plot(report.brake_time_s, report.tail_brake_force_N / 1e3,
            label=f"tail (vehicle {max(report.n_vehicles - 1, 0)})", ls="--")
    mark_command(ax)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("brake force [kN]")
    ax.set_title(f"Brake force, head wagon and tail {title}".strip(), parse_math=False)
    ax.grid(alpha=0.3)
    ax.legend()
    save(fig, "brake_force.png")

    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.add_subplot()
    j = np.arange(1, report.n_couplers + 1)
    ax.bar(j, report.coupler_peak_draft_N / 1e3, color="tab:red", label="peak draft (tension)")
    ax.bar(j, report.coupler_peak_buff_N / 1e3, color="tab:blue",
           label="peak buff (compression)")
    ax.axhline(0.0, color="k", lw=0.8)
    _limit_lines(ax, report, j)
    ax.set_xlabel("coupler (1 = behind the head)")
    ax.set_ylabel("coupler force [kN]  (draft +, buff -)")
    ax.set_title(f"Peak coupler forces along the train {title}".strip(), parse_math=False)
    ax.grid(alpha=0.3, axis="y")
    ax.legend()
    save(fig, "coupler_peaks.png")

    fig = Figure(figsize=(9, 4.8), layout="constrained")
    ax = fig.add_subplot()
    if report.heat_force_N.size:
        data = report.heat_force_N.T / 1e3
        lim = float(np.abs(data).max()) or 1.0
        t0, t1 = report.heat_t0_s, report.heat_t1_s
        last = max(t1[-1], t0[-1] + (t0[-1] - t0[-2])) if t0.size > 1 else t1[-1] + 1e-3
        x = np.append(t0, last)  # bin edges: each bin starts at its first sample
        y = np.arange(report.n_couplers + 1) + 0.5
        im = ax.pcolormesh(x, y, data, shading="flat", cmap="RdBu_r", rasterized=True,
                           norm=TwoSlopeNorm(vcenter=0.0, vmin=-lim, vmax=lim))
        fig.colorbar(im, ax=ax, label="coupler force [kN]  (draft +, buff -)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("coupler (1 = behind the head)")
    ax.set_title(f"Coupler force {title}".strip(), parse_math=False)
    save(fig, "coupler_force_map.png")
    if report.has_brake_pipe:
        cylinders = {} if not report.cylinder_time_s.size else {
            report.head_wagon_index: report.head_wagon_cylinder_Pa,
            max(report.n_vehicles - 1, 0): report.tail_cylinder_Pa}
        save(profiles_figure(report.pipe_distance_m, report.pipe_profile_time_s,
                             report.pipe_profile_Pa, report.cylinder_time_s, cylinders,
                             title=f"Brake pipe {title}".strip()), "brake_pipe.png")
    if report.temperature_time_s.size:
        fig = Figure(figsize=(8, 4.5), layout="constrained")
        ax = fig.add_subplot()
        ax.plot(report.temperature_time_s, report.hottest_block_K - 273.15,
                label="blocks (the hottest vehicle's)")
        ax.plot(report.temperature_time_s, report.hottest_wheel_K - 273.15,
                label="wheels (the hottest vehicle's)", ls="--")
        mark_command(ax)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("temperature [C]")
        ax.set_title(f"Brake heat {title}".strip() + f" (model {VALIDATION})",
                     parse_math=False)
        ax.legend(loc="best", fontsize=8)
        save(fig, "brake_temperature.png")
    report.plots = paths
    return paths


def legend_as_written(ax, handles, labels, **kw):
    """``ax.legend`` of ``handles`` with ``labels`` drawn as written: no label read as
    mathtext (``$...$``) and none left out for starting with ``_`` (as matplotlib does with
    the labels it collects itself)."""
    leg = ax.legend(handles, labels, **kw)
    for text in leg.get_texts():
        text.set_parse_math(False)
    return leg


def _limit_lines(ax, report: RunReport, couplers: np.ndarray) -> None:
    """Per-coupler limits of the verdicts as steps, where the peaks reach half of them (a
    line far beyond the bars would flatten them)."""
    lim = report.limits
    if lim is None or lim.draft_strength_N.size != couplers.size or not couplers.size:
        return
    draft = float(report.coupler_peak_draft_N.max())
    buff = float(-report.coupler_peak_buff_N.min())
    for values, peak, sign, label, style in (
            (lim.draft_strength_N, draft, 1.0, "draft strength", "-"),
            (lim.buff_strength_N, buff, -1.0, "buff strength", "-"),
            (lim.endurable_lcf_N, buff, -1.0, "endurable compressive force", "--")):
        finite = np.isfinite(values)
        if finite.any() and peak >= 0.5 * float(values[finite].min()):
            ax.step(couplers, sign * np.where(finite, values, np.nan) / 1e3, where="mid",
                    color="k", ls=style, lw=1, label=label)


def render_markers(specs, path, title: str = "", window_m: float = 120.0) -> Path:
    """Draw a plant's markers (:func:`~ltd_brake_ros.plant.markers.train_markers`) as a PNG.

    A side view of what RViz or Foxglove's 3D panel shows, x along the track [m] and z up
    [m]: the whole train above, the head end enlarged below; the boxes in their colours, the
    labels in the enlarged view.

    Parameters
    ----------
    specs : list of MarkerSpec
    path : str or path-like
        The PNG file (written whole or not at all).
    title : str, optional
    window_m : float, optional
        Track behind the head shown enlarged [m].

    Returns
    -------
    pathlib.Path
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    boxes = [m for m in specs if m.kind == "cube"]
    head = max(m.x + m.size[0] / 2 for m in boxes)
    tail = min(m.x - m.size[0] / 2 for m in boxes)
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    whole, near = fig.subplots(2, 1, height_ratios=(1, 1.6))
    for ax, left, labels in ((whole, tail, False), (near, max(tail, head - window_m), True)):
        for m in boxes:
            ax.add_patch(Rectangle((m.x - m.size[0] / 2, m.z - m.size[2] / 2), m.size[0],
                                   m.size[2], facecolor=m.rgba[:3], edgecolor="0.2",
                                   lw=0.4, zorder=3 if m.ns.endswith("couplers") else 2))
        for m in specs:
            if labels and m.kind == "text" and left <= m.x <= head:
                ax.text(m.x, 2.4, m.text, ha="center", va="center", fontsize=7,
                        parse_math=False)
        ax.plot([left - 2, head + 2], [0, 0], color="0.3", lw=1.5)  # the rail
        ax.set_xlim(left - 2, head + 2)
        ax.set_ylim(-0.5, 5.0)
        ax.set_yticks([])
    whole.set_title(title, fontsize=9, parse_math=False)
    near.set_xlabel("position along the track [m] (head to the right); enlarged: the "
                    "head end")
    p = Path(path)
    with replaced_file(p, "wb") as fh:
        fig.savefig(fh, format="png", dpi=130)
    return p
