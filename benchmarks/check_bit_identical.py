"""Check that this tree computes every result of a set of runs to the last bit as a given commit
does: for changes meant to make the code faster, not to change what it computes.

Each tree runs the same runs in a fresh process of this tree's Python environment (its
``PYTHONPATH`` puts the tree first); every result is turned into bytes (floats and arrays bit
for bit, NaN payloads and signed zeros included) and compared. The commit is extracted with
``git archive`` into a temporary folder, removed at the end; its kernels compile into that
folder on the first run (``--keep-old DIR`` keeps it for the next run).

The runs, each with the kernel state after the run (every array of ``KinematicState`` and of the
brake model's state), the counters, every chunk's snapshot (arrays, events, extras), the stops,
the verdicts, the brake temperatures, the adhesion records and the summary:

* scenario 6 (the paper's empirical model, 100 km/h) and scenario 12 (50 km/h): emergency stop
  in 1 s chunks until settled, then 5 s at rest; and the same stops through
  ``emergency_stop`` (chunks grouped while the stop is far): its summary;
* scenario 6 with the brake-pipe model (``brake_params/uic_brake_pipe.yaml``);
* E402B + 150 x 80 t in G from the head: local time stepping (its counters say so);
* scenario 6 on a wet rail and on a low-adhesion rail (wheel slide on: wheelsets lock and roll
  again on the low one);
* a command script on scenario 6's train from 60 km/h in 50 ms chunks: a service stop, a
  drive-off, an emergency stop;
* scenario 6 in 10 ms chunks for 5 s, then in 0.37 s chunks (whole steps, the temperatures
  brought to the end of chunks between their update times).

Usage::

    python benchmarks/check_bit_identical.py <commit>     # e.g. the commit before a change
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import math  # noqa: E402
import pickle  # noqa: E402
import shutil  # noqa: E402
import struct  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent.parent


# --------------------------------------------------------------------------- one process


#: Tags of :func:`flat`'s leaves (no field or key of a result is called so).
_ND, _F, _I, _B = "\0nd", "\0f", "\0i", "\0b"


def flat(value, depth: int = 0):
    """``value`` as plain, comparable data: floats and arrays as their bytes."""
    if depth > 8:
        return ("deep", type(value).__name__)
    if isinstance(value, np.ndarray):
        return (_ND, value.dtype.str, value.shape, np.ascontiguousarray(value).tobytes())
    if isinstance(value, (bool, np.bool_)):
        return (_B, bool(value))
    if isinstance(value, (float, np.floating)):
        return (_F, struct.pack("<d", float(value)))
    if isinstance(value, (int, np.integer)):
        return (_I, int(value))
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, dict):
        return ("dict", tuple((str(k), flat(v, depth + 1)) for k, v in value.items()))
    if isinstance(value, tuple) and hasattr(value, "_fields"):  # a named tuple
        return (type(value).__name__,
                tuple((k, flat(getattr(value, k), depth + 1)) for k in value._fields))
    if isinstance(value, (list, tuple)):
        return ("seq", tuple(flat(v, depth + 1) for v in value))
    if dataclasses.is_dataclass(value):
        return (type(value).__name__, tuple((f.name, flat(getattr(value, f.name), depth + 1))
                                            for f in dataclasses.fields(value)))
    if hasattr(value, "__dict__"):
        return (type(value).__name__, flat(vars(value), depth + 1))
    return ("repr", repr(value))


def _capture(sim, snaps: list) -> dict:
    """Everything a run leaves, as :func:`flat` data."""
    from ltd_brake_ros.studies.runs import summarize

    st = sim._state  # the check reaches into the simulator for the kernel's whole state
    summary = summarize(sim, 0.0).as_dict()
    summary = {k: v for k, v in summary.items() if not _timing(k)}
    out = {"kinematics": st.kinematics, "brakes": st.brakes, "stats": sim.stats,
           "time_s": sim.time_s, "stops": [s.as_dict() for s in sim.stops],
           "verdicts": sim.verdicts().as_dict(), "temperatures": sim.brake_temperatures(),
           "adhesion": sim.adhesion_records(), "wheel_slides": sim.wheel_slides(),
           "summary": summary}
    tag, items = flat(out)
    return tag, items + (("snapshots", ("seq", tuple(snaps))),)  # already flat


def _timing(key: str) -> bool:
    """A summary's timing field (CPU and wall time: not a result)."""
    return "wall" in key or "real_time" in key


def _snap(snaps: list):
    """An ``on_chunk`` that keeps every snapshot as :func:`flat` data."""
    return lambda snap: snaps.append(flat(vars(snap)))


def _consist(wagons: int, mass_t: float, position: str):
    from ltd_brake_ros.inputs import consist_from_mapping

    return consist_from_mapping({"name": "generated", "vehicles": [
        {"type": "E402B", "brake_position": position},
        {"type": "Shimmns", "count": wagons, "mass_t": mass_t, "brake_position": position}]},
        "<generated>")


def _stop(consist, speed_kmh, params=None, adhesion=None, rest_s=5.0) -> dict:
    """An emergency stop in 1 s chunks until settled, then ``rest_s`` at rest."""
    from ltd_brake_ros.studies.runs import emergency_run

    snaps: list = []
    sim = emergency_run(consist, speed_kmh, params, chunk_s=1.0, on_chunk=_snap(snaps),
                        adhesion=adhesion)
    for _ in range(int(rest_s)):
        snaps.append(flat(vars(sim.advance(1.0))))
    return _capture(sim, snaps)


def worker(out: Path) -> None:
    """Run every case; write their results to ``out`` (a pickle of plain data)."""
    from ltd_brake_ros.inputs import get_scenario, load_brake_params
    from ltd_brake_ros.api import load_commands
    from ltd_brake_ros.simulator import Commands, Simulator
    from ltd_brake_ros.studies.runs import emergency_stop, scripted_run

    paper = load_brake_params("brake_params/paper.yaml")
    s6, s12 = get_scenario(6), get_scenario(12)
    cases = {}
    cases["scenario 6"] = _stop(s6.consist(), s6.speed_kmh, paper)
    cases["scenario 12"] = _stop(s12.consist(), s12.speed_kmh, paper)
    for name, sc in (("scenario 6", s6), ("scenario 12", s12)):
        r = emergency_stop(sc.consist(), sc.speed_kmh, paper).as_dict()
        cases[name + ", emergency_stop (grouped chunks)"] = flat(
            {k: v for k, v in r.items() if not _timing(k)})
    cases["scenario 6, brake pipe"] = _stop(
        s6.consist(), s6.speed_kmh, load_brake_params("brake_params/uic_brake_pipe.yaml"))
    cases["E402B + 150 x 80 t G, local steps"] = _stop(_consist(150, 80.0, "G"), 100.0, paper)
    cases["scenario 6, wet rail"] = _stop(s6.consist(), s6.speed_kmh, paper, adhesion="wet")
    cases["scenario 6, low rail"] = _stop(s6.consist(), s6.speed_kmh, paper, adhesion="low")
    script = load_commands([
        {"t_s": 0.0, "brake_demand": 0.6},
        {"t_s": 45.0, "brake_demand": 0.0, "traction": 0.6},
        {"t_s": 85.0, "traction": 0.0, "emergency": True}])
    snaps: list = []
    sim = scripted_run(s6.consist(), 60.0, script, paper, chunk_s=0.05,
                       on_chunk=_snap(snaps))
    cases["command script: service stop, drive-off, emergency"] = _capture(sim, snaps)
    snaps = []
    sim = Simulator(s6.consist(), s6.speed_kmh, paper)
    snaps.append(flat(vars(sim.advance(0.01, Commands(emergency=True)))))
    for _ in range(499):
        snaps.append(flat(vars(sim.advance(0.01))))
    while sim.settled_time_s is None:
        snaps.append(flat(vars(sim.advance(0.37))))
    cases["scenario 6 in 10 ms and 0.37 s chunks"] = _capture(sim, snaps)
    # what the runs did, so that a reader sees the cases exercise what they name
    facts = {
        "stops of the command script": len(sim_stops(cases)),
        "local steps, 150 wagons": _stat(cases["E402B + 150 x 80 t G, local steps"],
                                         "local_steps"),
        "vehicles that slid, low rail": _slid(cases["scenario 6, low rail"]),
    }
    with open(out, "wb") as f:
        pickle.dump({"cases": cases, "facts": facts}, f)


def _get(case: tuple, key: str):
    """The entry ``key`` of a :func:`flat` dict or named tuple."""
    return dict(case[1])[key]


def sim_stops(cases: dict) -> tuple:
    return _get(cases["command script: service stop, drive-off, emergency"], "stops")[1]


def _stat(case: tuple, name: str) -> int:
    return _get(_get(case, "stats"), name)[1]


def _slid(case: tuple) -> int:
    return len(_get(case, "wheel_slides")[1])


# --------------------------------------------------------------------------- the parent


def _extract(commit: str, into: Path) -> None:
    into.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(HERE), "archive", "--format=tar", commit],
                             check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)


def _run(tree: Path, out: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), LTD_BRAKE_FIRST_RUN="wait",
               LTD_BRAKE_SERVER="off")
    env.pop("LTD_BRAKE_CONFIG", None)
    subprocess.run([sys.executable, str(Path(__file__).resolve()), "--worker", str(out)],
                   env=env, cwd=str(tree), check=True)
    with open(out, "rb") as f:
        return pickle.load(f)


def _first_difference(a, b, path: str = "") -> str | None:
    """Where two :func:`flat` values first differ (None: equal)."""
    if type(a) is not type(b):
        return f"{path}: {type(a).__name__} / {type(b).__name__}"
    if isinstance(a, tuple):
        if len(a) != len(b):
            return f"{path}: length {len(a)} / {len(b)}"
        if a and a[0] == _ND:
            if a != b:
                x = np.frombuffer(a[3], a[1]).reshape(a[2]) if a[2] == b[2] else None
                y = np.frombuffer(b[3], b[1]).reshape(b[2]) if a[2] == b[2] else None
                where = "" if x is None else f" (first at {np.argwhere(x != y)[:1].tolist()})"
                return f"{path}: arrays differ{where}"
            return None
        for i, (x, y) in enumerate(zip(a, b)):
            key = x[0] if isinstance(x, tuple) and len(x) == 2 and isinstance(x[0], str) else i
            d = _first_difference(x, y, f"{path}/{key}")
            if d:
                return d
        return None
    return None if a == b else f"{path}: {a!r} / {b!r}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("commit", nargs="?", help="the commit to compare with")
    parser.add_argument("--keep-old", metavar="DIR", type=Path,
                        help="extract the commit here (reused if present) and keep it")
    parser.add_argument("--worker", metavar="OUT", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args.worker)
        return
    if not args.commit:
        parser.error("give the commit to compare with")
    tmp = Path(tempfile.mkdtemp(prefix="ltd_bit_identical_"))
    try:
        old = args.keep_old.resolve() if args.keep_old else tmp / "old"
        if not (old / "ltd_brake_ros").is_dir():
            _extract(args.commit, old)
        theirs = _run(old, tmp / "old.pickle")
        ours = _run(HERE, tmp / "new.pickle")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"this tree against {args.commit}, bit for bit:")
    failed = 0
    for name, result in ours["cases"].items():
        other = theirs["cases"].get(name)
        diff = "missing" if other is None else _first_difference(other, result)
        failed += diff is not None
        print(f"  {name}: {'identical' if diff is None else 'DIFFERENT: ' + diff}"
              f" ({_size(result)} values compared)")
    print("  " + "; ".join(f"{k}: {v}" for k, v in ours["facts"].items()))
    print("all identical" if not failed else f"{failed} case(s) differ")
    sys.exit(1 if failed else 0)


def _size(value) -> int:
    """Numbers in a :func:`flat` value."""
    if isinstance(value, tuple):
        if value and value[0] == _ND:
            return int(math.prod(value[2])) if value[2] else 1
        if value and value[0] in (_F, _I, _B):
            return 1
        return sum(_size(v) for v in value)
    return 0


if __name__ == "__main__":
    main()
