"""Re-running chosen runs of a campaign with a full recording, as the live plant records them.

Run ``i`` is rebuilt from the campaign alone (its draws come from the seed and ``i``, see
:mod:`.campaign`) and simulated offline with the campaign's integration steps: each chunk of
the campaign (:data:`~.campaign.CHUNK_S` or :data:`~.campaign.SCRIPT_CHUNK_S`) is advanced in
sub-chunks of about :data:`RECORD_CHUNK_S`, a whole number of the campaign's steps each, and
the state after every sub-chunk is written to a rosbag2/MCAP folder with the topics, types,
QoS, sign conventions and run information of a ``sim_node`` recording (vehicle arrays,
``/clock``, the command topics; no ``/diagnostics``, which reports the live plant's pacing).
The payloads are encoded by :mod:`..recording.cdr_encode`, so nothing here needs ROS at run
time; the message definitions written into the file are read from the installed ROS message
packages (:mod:`..recording.ros_types`).
"""
from __future__ import annotations

import logging
import math
from pathlib import Path

from ..inputs import InputError, consist_from_mapping
from ..inputs.campaign import Campaign, load_campaign
from ..plant.recorder import Recorder
from ..plant.settings import StartupError
from ..recording.cdr_encode import encode_bool, encode_float64
from ..recording.metadata import run_metadata, train_description
from ..recording.plant_topics import COMMAND_TOPICS, StateEncoder, plant_topics, qualify
from ..simulator import Commands, SimulationError, Simulator
from .campaign import CHUNK_S, SCRIPT_CHUNK_S, draw, models
from .runs import stop_run_over

__all__ = ["RECORD_CHUNK_S", "campaign_of_results", "rerun", "run_folder_name"]

#: Target interval between recorded states [s] (the node's default ``chunk_s``).
RECORD_CHUNK_S = 0.02
#: Longest emergency stop simulated [s] (as :func:`.runs.emergency_stop`).
MAX_STOP_S = 600.0
#: The plant input -> its command topic.
_TOPIC_OF_INPUT = {name: topic for topic, (_, name) in COMMAND_TOPICS.items()}

_log = logging.getLogger(__name__)


def campaign_of_results(folder, manifest: dict) -> Campaign:
    """The campaign a results folder was run from.

    The campaign file named in the manifest if it is unchanged (its files are found beside
    it), else the copy in the folder; either must have the digest the manifest states.

    Parameters
    ----------
    folder : path-like
        Results folder of ``ltd-brake campaign run``.
    manifest : dict
        Its manifest (:func:`~.campaign_exec.read_results`).

    Returns
    -------
    Campaign

    Raises
    ------
    InputError
        No campaign file with the recorded digest.
    """
    folder = Path(folder)
    tried = []
    for path in (manifest.get("campaign_file"), folder / "campaign.yaml"):
        if path and Path(path).is_file():
            c = load_campaign(path)
            if c.digest == manifest.get("digest"):
                _check_inputs(c, manifest, folder)
                return c
            tried.append(str(path))
    raise InputError(folder / "manifest.json", "digest", "no campaign file with this digest: "
                     + (f"{', '.join(tried)} changed since the run" if tried else
                        "campaign.yaml is missing"))


def _check_inputs(c: Campaign, manifest: dict, folder: Path) -> None:
    """The model files a re-run reads must be those the results were made with."""
    before = manifest.get("inputs")
    if not isinstance(before, dict):
        return  # results made before inputs were pinned: the re-run compares every row
    for path, digest in c.inputs.items():
        if path.endswith("campaign.yaml") or Path(path) == Path(c.source).resolve():
            continue  # the campaign file itself: its digest was checked
        if before.get(path, digest) != digest:
            raise InputError(folder / "manifest.json", "inputs", f"{path} changed since the "
                             "results were made; a re-run would not reproduce them (restore "
                             "the file)")


def run_folder_name(run_id: int, manoeuvre: str) -> str:
    """Folder name of a re-run: ``run_<id>_<manoeuvre>``."""
    return f"run_{run_id:06d}_{manoeuvre}"


def _sub_chunks(duration_s: float, step_s: float) -> tuple[int, float]:
    """Sub-chunks of a campaign chunk and their length [s]: a whole number of its steps each."""
    steps = max(1, math.ceil(duration_s / step_s - 1e-9))
    h = duration_s / steps
    per = max(1, round(RECORD_CHUNK_S / h))
    while steps % per:  # the largest divisor of the chunk's steps not above the target
        per -= 1
    return steps // per, h * per


def rerun(c: Campaign, run_id: int, manoeuvre: str, out, *, namespace: str = "/") -> dict:
    """Run one train of a campaign under one manoeuvre again, recording it.

    Parameters
    ----------
    c : Campaign
    run_id : int
        0 <= run_id < c.runs.
    manoeuvre : str
        Name of one of the campaign's manoeuvres.
    out : path-like
        Bag folder to create (it must not exist or be empty).
    namespace : str, optional
        Namespace of the plant topics (``/`` as a node started without one).

    Returns
    -------
    dict
        ``folder``, ``run_id``, ``manoeuvre``, ``messages``, and the run's
        ``stopping_distance_m`` (NaN without a stop), ``peak_draft_kN``, ``peak_draft_coupler``,
        ``peak_buff_kN``, ``peak_buff_coupler`` as the simulator found them (every step).

    Raises
    ------
    InputError
        ``run_id`` or ``manoeuvre`` not in the campaign, ``out`` not empty or not writable,
        or the ROS message packages (for the definitions in the file) not installed.
    SimulationError
        The run fails (as it failed in the campaign).
    OSError
        The recording cannot be written.
    """
    if not 0 <= run_id < c.runs:
        raise InputError(c.source, "runs", f"run {run_id} is not in the campaign "
                         f"(0 to {c.runs - 1})")
    m = next((m for m in c.manoeuvres if m.name == manoeuvre), None)
    if m is None:
        raise InputError(c.source, "manoeuvres", f"no manoeuvre {manoeuvre!r}; the campaign has "
                         f"{', '.join(x.name for x in c.manoeuvres)}")
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(out, "", "exists and is not empty: give a new folder")
    sample, data = draw(c, run_id)
    consist = consist_from_mapping(data, f"{c.source} run {run_id}")
    params, lut = models(c, sample)
    speed = sample["speed_kmh"][m.name]
    sim = Simulator(consist, speed, params, lut, step_s=c.step_s)
    if m.kind == "emergency":
        script, chunk_s, end_s = [(0.0, {"emergency": True})], CHUNK_S, MAX_STOP_S
    elif m.kind == "service":
        script = [(0.0, {"brake_demand": m.demand})]
        if m.release_s < m.duration_s:
            script.append((m.release_s, {"brake_demand": 0.0}))
        chunk_s, end_s = SCRIPT_CHUNK_S, m.duration_s
    else:
        script, chunk_s, end_s = [(0.0, {"traction": m.demand})], SCRIPT_CHUNK_S, m.duration_s
    meta = run_metadata(
        sim, scenario=f"{c.name} run {run_id} {m.name}", campaign=c.name,
        campaign_file=str(c.source), campaign_digest=c.digest, run_id=run_id, manoeuvre=m.name,
        manoeuvre_kind=m.kind, sample=sample, brake_params=str(params.source),
        coupler_lut=str(lut.source),
        **({"command_time_s": 0.0} if m.kind != "traction_start" else {}))  # a brake command
    # the node's messages: arrays, stamped state, the brake model's extras, /clock
    extras = tuple(sim.snapshot().extras)
    encoder = StateEncoder(sim.n, sim.model.train.centre_offset_m, extras=extras,
                           description=train_description(sim, meta))
    rec = Recorder(str(out), plant_topics(namespace, extras), _log, metadata=meta)
    messages = [0]

    def write(topic: str, data: bytes, t_ns: int) -> None:
        rec.write(topic, data, t_ns)
        messages[0] += 1

    def publish(snap) -> int:
        t_ns = round(snap.time_s * 1e9)  # the node's stamp of a state
        for topic, data in encoder.encode(snap, t_ns):
            write(qualify(namespace, topic), data, t_ns)
        return t_ns

    def command(name: str, value, t_ns: int) -> None:
        write(qualify(namespace, _TOPIC_OF_INPUT[name]),
              encode_bool(value) if name == "emergency" else encode_float64(value), t_ns)

    try:
        rec.open()
    except StartupError as exc:
        raise InputError(out, "", exc.reason) from None
    except (LookupError, ImportError) as exc:  # the message definitions written into the file
        raise InputError("ROS message packages", "", f"{exc}: a recording needs std_msgs and "
                         "rosgraph_msgs installed") from None
    try:
        t_ns = _drive(sim, script, chunk_s, end_s, m.kind == "emergency", publish, command,
                      publish(sim.snapshot()))
        for topic, data in StateEncoder.encode_events(sim.end_events()):  # the open stop
            write(qualify(namespace, topic), data, t_ns)
    finally:
        rec.close()
    if rec.error:
        raise OSError(f"recording {out} failed: {rec.error}")
    peaks = sim.coupler_peaks()
    stop = sim.stopping_distance_m
    return {"folder": str(out), "run_id": run_id, "manoeuvre": m.name, "messages": messages[0],
            "stopping_distance_m": math.nan if stop is None else float(stop),
            "peak_draft_kN": peaks.draft_N / 1e3, "peak_draft_coupler": peaks.draft_coupler,
            "peak_buff_kN": peaks.buff_N / 1e3, "peak_buff_coupler": peaks.buff_coupler}


def _drive(sim: Simulator, script, chunk_s: float, end_s: float, until_stop: bool, publish,
           command, t_ns: int) -> int:
    """Advance as the campaign does (:func:`.runs.emergency_stop`, :func:`.runs.scripted_run`).

    The campaign's chunks, each cut into sub-chunks whose states are published; the inputs
    change at the campaign's chunk boundaries, each change recorded on its command topic.
    Returns the last state's stamp [ns].
    """
    state: dict = {}
    k = 0
    while sim.time_s < end_s - 1e-9 or (until_stop and sim.stop_time_s is not None):
        if until_stop and sim.time_s >= MAX_STOP_S and sim.stop_time_s is None:
            break
        changed = {}
        while k < len(script) and script[k][0] <= sim.time_s + 1e-9:
            changed.update(script[k][1])
            k += 1
        for name, value in changed.items():
            command(name, value, t_ns)
        state.update(changed)
        chunk = chunk_s if until_stop else min(chunk_s, end_s - sim.time_s)
        n, sub = _sub_chunks(chunk, sim.step_s)
        commands = Commands(**state) if (changed or not until_stop) else None
        for _ in range(n):
            t_ns = publish(sim.advance(sub, commands))
            commands = None if until_stop else commands
        if until_stop and stop_run_over(sim):  # settled, as the campaign's run
            return t_ns
    if until_stop:
        raise SimulationError(f"the train had not stopped after {MAX_STOP_S:g} s")
    return t_ns
