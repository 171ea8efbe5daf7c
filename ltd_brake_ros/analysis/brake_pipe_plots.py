"""Plots of the brake pipe: pipe pressure along the train at instants, cylinder pressures in time.

For runs with a brake model that shows ``brake_pipe_pressure_Pa`` and
``brake_cylinder_pressure_Pa`` (the UIC brake pipe); the inputs are plain arrays, as a
recording's ``vehicles/brake_pipe_pressure`` and ``vehicles/brake_cylinder_pressure`` topics or
a :class:`~ltd_brake_ros.studies.brake_pipe_validation.History` give them.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ..outputs import replaced_file

__all__ = ["pipe_figure", "profiles_figure", "write_brake_pipe_plot"]

BAR = 1e5


def _instants(time_s: np.ndarray, instants_s: Sequence[float] | None, count: int) -> list[int]:
    if instants_s is None:
        instants_s = np.linspace(time_s[0], time_s[-1], count)
    return sorted({int(np.clip(np.searchsorted(time_s, t), 0, time_s.size - 1))
                   for t in instants_s})


def pipe_figure(time_s, distance_m, pipe_Pa, cylinder_Pa, *,
                instants_s: Sequence[float] | None = None, vehicles: Sequence[int] = (1, -1),
                title: str = ""):
    """Figure of pipe pressure along the train and cylinder pressure of chosen vehicles.

    Parameters
    ----------
    time_s : array_like, shape (m,)
        Sample times [s].
    distance_m : array_like, shape (n,)
        Each vehicle's distance from the head (or from the venting vehicle) [m].
    pipe_Pa, cylinder_Pa : array_like, shape (m, n)
        Gauge brake-pipe and brake-cylinder pressures [Pa].
    instants_s : sequence of float, optional
        Times of the pipe profiles [s] (default: six evenly spread).
    vehicles : sequence of int, optional
        Vehicles whose cylinder pressure is drawn (default the first wagon and the tail).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
        As :func:`profiles_figure`.
    """
    t = np.asarray(time_s, float)
    p = np.asarray(pipe_Pa, float)
    c = np.asarray(cylinder_Pa, float)
    k = _instants(t, instants_s, 6)
    n = c.shape[1]
    return profiles_figure(distance_m, t[k], p[k], t, {i % n: c[:, i % n] for i in vehicles},
                           title=title)


def profiles_figure(distance_m, profile_time_s, profile_Pa, time_s, cylinder_Pa: dict, *,
                    title: str = ""):
    """Figure of pipe-pressure profiles along the train and cylinder pressures in time.

    The reduced form of :func:`pipe_figure`: only the profiles and the cylinder series drawn.

    Parameters
    ----------
    distance_m : array_like, shape (n,)
        Each vehicle's distance from the head [m].
    profile_time_s : array_like, shape (k,)
        Time of each profile [s].
    profile_Pa : array_like, shape (k, n)
        Gauge brake-pipe pressure of every vehicle at those times [Pa].
    time_s : array_like, shape (m,)
        Sample times of the cylinder pressures [s].
    cylinder_Pa : dict of int to array_like, shape (m,)
        Gauge brake-cylinder pressure [Pa] of each vehicle drawn (key: vehicle index, 0 = head).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
        Left: pipe pressure [bar] against distance at each instant; right: cylinder
        pressures [bar] against time.
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    x = np.asarray(distance_m, float)
    fig = Figure(figsize=(11, 4.2))
    left, right = fig.subplots(1, 2)
    marker = "." if x.size <= 100 else None  # dots would hide the lines of a long train
    times = np.asarray(profile_time_s, float)
    colours = colormaps["viridis"](np.linspace(0.0, 0.9, max(times.size, 1)))  # dark: early
    for tk, pk, colour in zip(times, np.asarray(profile_Pa, float), colours):
        left.plot(x, pk / BAR, marker=marker, ms=3, lw=1, color=colour, label=f"{tk:.1f} s")
    left.set_xlabel("distance along the train [m]")
    left.set_ylabel("brake-pipe pressure [bar, gauge]")
    left.legend(fontsize=8, title="time")
    left.grid(alpha=0.3)
    for j, c in cylinder_Pa.items():
        right.plot(time_s, np.asarray(c, float) / BAR, lw=1.2, label=f"vehicle {j}")
    right.set_xlabel("time [s]")
    right.set_ylabel("brake-cylinder pressure [bar, gauge]")
    right.legend(fontsize=8)
    right.grid(alpha=0.3)
    if title:
        fig.suptitle(title, parse_math=False)  # a name, drawn as written
    fig.tight_layout()
    return fig


def write_brake_pipe_plot(path, time_s, distance_m, pipe_Pa, cylinder_Pa, **options) -> Path:
    """Write :func:`pipe_figure` as a PNG file.

    Parameters
    ----------
    path : str or path-like
    time_s, distance_m, pipe_Pa, cylinder_Pa, **options
        As :func:`pipe_figure`.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    OSError
        The file cannot be written (no half-written file is left).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = pipe_figure(time_s, distance_m, pipe_Pa, cylinder_Pa, **options)
    FigureCanvasAgg(fig)
    p = Path(path)
    with replaced_file(p, "wb") as fh:
        fig.savefig(fh, format="png", dpi=120)
    return p
