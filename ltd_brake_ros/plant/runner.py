"""The plant thread: advances the simulator in chunks, paced by a clock it is given.

One thread owns the simulator and does every advance and every publication; other threads
(a ROS executor, a test) only queue jobs (:meth:`PlantRunner.submit`) that the plant thread runs
between two chunks. So a chunk is always advanced and published in one place and lock-step runs
are deterministic. Free-running chunks are due at ``start + k * chunk_s / real_time_factor`` on
the wall clock, and none runs before it is due. A plant that finishes a chunk after the next one
was due is behind its schedule: by at most ``max_catch_up_s`` it catches up, advancing the
chunks already due at once (a fixed-timestep loop's bounded catch-up); further behind, it counts
an overrun and restarts the schedule from now. A plant that follows another plant's clock
(``follow_clock``) advances instead to the times it is given (:meth:`PlantRunner.follow`), so
several trains share one simulated time.

Nothing here imports ROS: the host passes callbacks that publish a state, publish a diagnostics
report and observe a handled input, a logger, and the clock (:class:`~.pacing.Clock`), so pacing,
lock-step and the run policy are tested with a fake clock.

A step of any length stays interruptible: between two of its chunks the plant serves the urgent
requests (pause and resume, the real-time factor, the simulation state) and shutdown; a pause
of a lock-step plant (or the resumption of a paused free-running one) ends the step there.
Inputs, resets and further steps wait for the step's end, so a step runs with the commands
that reached the plant before it, whatever its length.
"""
from __future__ import annotations

import math
import queue
import threading
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping

from ..inputs.commands import COMMAND_RANGES, VALVE_POSITIONS, valve_position
from ..simulator import Commands, SimulationError, Simulator, Snapshot
from .diagnostics import (DIAGNOSTICS_PERIOD_S, DIAGNOSTICS_SIM_PERIOD_S, PaceWindow,
                          PlantStatus, format_fixed, plant_status)
from .pacing import Clock, Pacer
from .recorder import Recorder
from .settings import PlantSettings, StartupError

#: Tolerance when comparing simulated times built from summed chunks [s].
TIME_EPS_S = 1e-9
#: Pacing lateness samples kept for statistics (bounded: memory stays flat on long runs).
LATENESS_SAMPLES = 10_000
#: Wall time between two warnings about rejected inputs of one kind [s].
REJECT_LOG_PERIOD_S = 2.0
#: A command flood keeps the receiving thread busy. From this long before a chunk is due until
#: the plant has published it, a receiving callback steps aside (sleeps: frees the GIL and
#: the CPU) so the plant keeps its deadline on a loaded machine [s]; checked every
#: YIELD_POLL_S, for at most YIELD_MAX_S per message.
YIELD_LEAD_S = 0.002
YIELD_POLL_S = 0.0005
YIELD_MAX_S = 0.01
#: As fast as possible, the plant thread offers the GIL to the receiving thread after holding it
#: this long [s]. The compiled kernel runs without the GIL (a receiving thread runs meanwhile),
#: so its time does not count: a long train, whose chunks are mostly kernel, rarely needs to
#: yield, and each yield can cost a scheduler time slice on a busy machine.
GIL_YIELD_PERIOD_S = 0.02
#: Inputs the plant takes: the emergency brake (bool), the numeric :data:`COMMAND_RANGES` and
#: the driver's brake valve position (str, a key of :data:`VALVE_POSITIONS`).
INPUTS = ("emergency", *COMMAND_RANGES, "driver_brake_valve")
#: Wall time a following plant advances in one go before it serves its queued requests (a
#: service, a reset, shutdown) and goes on [s]: a followed clock that jumps far ahead is
#: caught up in slices, never in one uninterruptible advance.
FOLLOW_SLICE_S = 0.05
#: A followed clock further ahead than this is a jump, logged once with the gap [s simulated].
FOLLOW_JUMP_S = 60.0
#: States of the simulation (:meth:`PlantRunner.simulation_state`,
#: :meth:`PlantRunner.set_simulation_state`): time advances by itself; time holds (stepping
#: advances it); stopped (reset to t = 0 and holding); the node is shutting down.
PLAYING, PAUSED, STOPPED, QUITTING = "playing", "paused", "stopped", "quitting"
#: Why a following plant refuses to be stepped or paused.
FOLLOWING = ("this plant follows the clock of another (clock:=follow): it advances with that "
             "clock; step or pause the plant that publishes it")


@dataclass
class PacingStats:
    """What pacing cost since start-up (read by diagnostics and the benchmark).

    Attributes
    ----------
    chunks : int
        Chunks advanced and published.
    overruns : int
        Times the plant finished a chunk more than ``max_catch_up_s`` after the next one was
        due (the schedule restarted then).
    caught_up : int
        Chunks finished after the next one was due, but within ``max_catch_up_s``: the next
        ran at once.
    max_lag_s : float
        Largest lag behind the schedule after a chunk (finish minus the next chunk's
        deadline) [s wall].
    dropped_s : float
        Lag given up by the overruns, summed: simulated time fell behind the wall clock by
        this much times the real-time factor [s wall].
    lateness_s : deque of float
        Publication time minus deadline of the most recent paced chunks [s].
    """

    chunks: int = 0
    overruns: int = 0
    caught_up: int = 0
    max_lag_s: float = 0.0
    dropped_s: float = 0.0
    lateness_s: deque = field(default_factory=lambda: deque(maxlen=LATENESS_SAMPLES))


class Job:
    """Work for the plant thread; another thread may wait for its ``result``."""

    __slots__ = ("fn", "done", "result")

    def __init__(self, fn: Callable[[], Any]):
        self.fn, self.done, self.result = fn, threading.Event(), None

    def run(self, log_error: Callable[[str], None] | None) -> None:
        """Run ``fn`` (on the plant thread); an exception is its failure, never the plant's."""
        try:
            self.result = self.fn()
        except Exception as exc:  # noqa: BLE001 - a bad job must not stop the plant
            if log_error is not None:  # else: shutting down, the outputs are gone
                log_error(f"{type(exc).__name__}: {exc}")
            self.result = (False, f"{type(exc).__name__}: {exc}")
        finally:
            self.done.set()


class PlantRunner:
    """Runs a simulator as a live plant (see the module docstring).

    Parameters
    ----------
    sim : Simulator
        Advanced only by the plant thread once :meth:`start` ed.
    settings : PlantSettings
    publish_state : callable
        ``publish_state(snapshot)`` after every chunk and reset (and once at the start);
        :attr:`stamp_ns` is the snapshot's time then.
    publish_status : callable
        ``publish_status(PlantStatus)`` about once per wall second.
    log : logger
        Has ``debug``, ``info``, ``warning``, ``error`` and ``fatal``.
    input_handled : callable, optional
        ``input_handled(name, value, message)`` for every input the plant takes, accepted or
        not, before it is applied (``message`` is what :meth:`receive` was given, None for the
        plant's own auto brake).
    recorder : Recorder, optional
        Its lifecycle follows the run (flushed when due, reopened on reset, closed on failure
        and close).
    publish_end : callable, optional
        ``publish_end(events)`` with the run's :meth:`~ltd_brake_ros.simulator.Simulator.
        end_events` as a run ends (a reset, a failure, the plant's close), before its recording
        is finished.
    labels : mapping, optional
        Input name to the name used in log lines (e.g. the topic).
    clock : Clock, optional
        Wall clock, sleep and wait primitives.
    host_ok : callable, optional
        ``host_ok() -> bool``; False once the host is shutting down (errors are then expected
        and not logged).
    """

    def __init__(self, sim: Simulator, settings: PlantSettings, *,
                 publish_state: Callable[[Snapshot], None],
                 publish_status: Callable[[PlantStatus], None], log,
                 input_handled: Callable[[str, Any, Any], None] | None = None,
                 recorder: Recorder | None = None, labels: Mapping[str, str] | None = None,
                 clock: Clock = Clock(), host_ok: Callable[[], bool] = lambda: True,
                 publish_end: Callable[[list], None] | None = None):
        self.sim, self.settings, self.recorder = sim, settings, recorder
        self._publish_end = publish_end
        self._ended_run = -1  # the run (number of resets before it) whose end was published
        self._publish_state, self._publish_status = publish_state, publish_status
        self._input_handled = input_handled or (lambda name, value, message: None)
        self._log, self._clock, self._host_ok = log, clock, host_ok
        self._labels = dict(labels or {})
        self.real_time_factor = settings.real_time_factor
        #: Chunks advanced per :meth:`step` request (may change at run time).
        self.steps_per_call = settings.steps_per_call
        self.stats = PacingStats()
        #: Set when the plant should shut down (a run-policy limit, or the plant thread died).
        self.finished = threading.Event()
        #: Why it finished (for diagnostics).
        self.finish_reason = ""
        #: 1 once the plant thread died of an unexpected error.
        self.exit_status = 0
        #: Why the simulator stopped advancing (None while it works; :meth:`reset` clears it).
        self.failure: str | None = None
        self.paused = False
        #: The inputs in force.
        self.commands = Commands()
        #: Inputs handled (received or self-issued), accepted or rejected.
        self.handled = 0
        #: Resets done (a refused one does not count).
        self.resets = 0
        self.rejected: dict[str, int] = {}
        #: Simulated time of the last advanced (published or not) state [ns].
        self.stamp_ns = 0
        #: Chunks advanced since the last reset (``publish_every`` counts them).
        self.run_chunks = 0
        #: The latest time of the followed clock [s] (None before the first).
        self.follow_target_s: float | None = None
        self._follow_pending = False
        self._catching_up = False
        #: Times the followed clock went back since the last reset.
        self.clock_backs = 0
        self._next_clock_back_log = 0.0
        self._catching_up = False
        self._next_reject_log: dict[str, float] = {}
        self._auto_brake_done = False
        self._lut_warned = False
        self._limits_logged: set[str] = set()  # criteria whose first exceedance was logged
        self._jobs: queue.SimpleQueue[Job] = queue.SimpleQueue()
        #: Jobs served between two chunks of a step too (:meth:`submit` ``urgent``).
        self._urgent: queue.SimpleQueue[Job] = queue.SimpleQueue()
        #: True from a request to stop (reset and hold) until the plant moves again.
        self.stopped = False
        self._wake = threading.Event()
        self._quit = threading.Event()
        self._thread = threading.Thread(target=self.run, name="plant", daemon=True)
        now = clock.monotonic()
        self._pacer = Pacer(self.real_time_factor, monotonic=clock.monotonic)
        self._next_index = 1
        self._window = PaceWindow(now)
        self._next_status_wall = 0.0
        self._next_status_sim = DIAGNOSTICS_SIM_PERIOD_S
        self._gil_held_s = 0.0
        self._last_chunk_end = now
        #: Wall time of the last ``Simulator.advance`` [s] (its compiled part frees the GIL).
        self.advance_wall_s = 0.0

    # ------------------------------------------------------------------ any thread

    @property
    def sim_time_s(self) -> float:
        """Simulated time of the last advanced state [s]."""
        return self.stamp_ns / 1e9

    def start(self) -> None:
        """Start the plant thread (publishes the initial state, then runs)."""
        self._thread.start()

    def close(self) -> None:
        """Stop the plant thread and finish the recording."""
        self._quit.set()
        self._wake.set()
        if self._thread.is_alive():
            self._thread.join(timeout=10.0)
        if not self._thread.is_alive():  # the plant thread no longer touches the simulator
            self._end_run()
        if self.recorder is not None:
            self.recorder.close()

    def submit(self, fn: Callable[[], Any], urgent: bool = False) -> Job:
        """Queue ``fn`` to run on the plant thread between two chunks.

        Parameters
        ----------
        fn : callable
        urgent : bool, optional
            Also between two chunks of a step (which holds the others until it ends): for
            requests that must not wait for a long step (pause, real-time factor, state).
        """
        job = Job(fn)
        (self._urgent if urgent else self._jobs).put(job)
        self._wake.set()
        return job

    def result(self, job: Job) -> tuple[bool, str]:
        """Wait for a request's ``(success, message)``; a failure if the plant is not running."""
        while not self._clock.wait(job.done, 0.5):
            if not self._thread.is_alive():
                return False, "the plant is not running (shutting down)"
        return job.result

    def receive(self, name: str, value: Any, message: Any = None) -> Job:
        """Queue an input: ``emergency`` (bool), a key of :data:`COMMAND_RANGES` (float) or
        ``driver_brake_valve`` (a position name)."""
        if name not in INPUTS:
            raise KeyError(f"unknown input {name!r}; expected one of {', '.join(INPUTS)}")
        return self.submit(lambda: self._on_input(name, value, message))

    def reset(self, replacement: tuple[Simulator, PlantSettings] | None = None,
              recording: tuple[list, dict] | None = None, hold: bool = False) -> Job:
        """Request the initial state (t = 0, brake released); a new bag when recording.

        Parameters
        ----------
        replacement : (Simulator, PlantSettings), optional
            A new run (other train, speed, files, run policy) to start instead of the
            current one; ``chunk_s``, ``lockstep``, ``follow_clock`` and ``publish_every``
            stay those in force.
        recording : (list, dict), optional
            Topics and metadata of the new run's bag (see :meth:`Recorder.reopen`).
        hold : bool, optional
            Stop: pause at t = 0 (a lock-step plant refuses steps) until played or paused
            (:meth:`set_simulation_state`).
        """
        return self.submit(lambda: self._reset(replacement, recording, hold))

    def pause(self, pause: bool) -> Job:
        """Request a pause (True) or the end of one (False); served within a chunk, during a
        step too (which it ends, if the plant can no longer be stepped)."""
        return self.submit(lambda: self._pause(bool(pause)), urgent=True)

    def step(self, chunks: int | None = None) -> Job:
        """Request ``chunks`` chunks, by default :attr:`steps_per_call` (lock-step mode or
        paused only)."""
        chunks = self.steps_per_call if chunks is None else int(chunks)
        return self.submit(lambda: self._step(chunks))

    def simulation_state(self) -> tuple[str, str]:
        """The state of the simulation and a line on it, read from any thread.

        Returns
        -------
        state : str
            :data:`QUITTING` once the run ended (the node shuts down), :data:`STOPPED` after
            a stop request until the plant moves again, :data:`PLAYING` while simulated time
            advances by itself (free-running, or following a clock), else :data:`PAUSED` (a
            lock-step plant between steps, a paused plant, a failed one).
        why : str
            Empty, or what holds the plant (a failure, a pause of a lock-step plant).
        """
        if self.finished.is_set():
            return QUITTING, self.finish_reason
        if self.failure:
            return PAUSED, f"simulation failed: {self.failure}; reset it"
        if self.stopped:
            return STOPPED, ""
        if self.settings.follow_clock:
            return PLAYING, "it advances with the clock it follows"
        if self.settings.lockstep:
            return PAUSED, ("held by ~/pause: steps are refused until it is resumed"
                            if self.paused else "")
        return (PAUSED if self.paused else PLAYING), ""

    def set_simulation_state(self, target: str) -> Job:
        """Request :data:`PLAYING`, :data:`PAUSED` or :data:`QUITTING`; served within a chunk,
        during a step too. The job's result is ``(outcome, message)``.

        ``outcome`` is ``ok``, ``already`` (the plant was in that state), ``refused`` (no such
        transition from here, or for this plant) or ``failed`` (the plant failed).
        :data:`PLAYING` resumes a paused free-running plant (a lock-step plant advances only
        when stepped); :data:`PAUSED` pauses one, or lets a held lock-step plant be stepped
        again; :data:`QUITTING` ends the run (the node shuts down). A stop is a reset with
        ``hold`` (:meth:`reset`), after :meth:`stop_refusal`.
        """
        return self.submit(lambda: self._set_state(target), urgent=True)

    def stop_refusal(self) -> tuple[str, str] | None:
        """``(outcome, message)`` when a stop cannot or need not happen, else None."""
        if self.finished.is_set():
            return "refused", (f"the run has ended ({self.finish_reason}); the node is "
                               "shutting down")
        if self.settings.follow_clock:
            return "refused", FOLLOWING
        if self.stopped:
            return "already", "stopped at t = 0 s"
        return None

    def follow(self, time_ns: int) -> None:
        """Let a following plant advance to the followed clock's ``time_ns`` [ns].

        Whole chunks are advanced while they end at or before that time; only the latest
        time counts when several arrive before the plant thread gets to them.
        """
        self.follow_target_s = time_ns / 1e9
        if not self._follow_pending:
            self._follow_pending = True
            self.submit(self._follow)

    def set_real_time_factor(self, value: float) -> Job:
        """Request a new real-time factor; the schedule restarts from now (served within a
        chunk, during a step too)."""
        return self.submit(lambda: self._set_real_time_factor(value), urgent=True)

    def yield_to_plant(self) -> None:
        """On a receiving thread: wait while a paced chunk is due (see YIELD_LEAD_S).

        Reads the plant's schedule without a lock: a torn read costs at most one needless
        or missed pause, never a wrong chunk. The inputs themselves are never dropped here.
        """
        if self.real_time_factor <= 0.0 or not self._free_running():
            return
        monotonic = self._clock.monotonic
        end = monotonic() + YIELD_MAX_S
        while True:
            now = monotonic()
            if now < self._due() - YIELD_LEAD_S or now >= end:
                return
            self._clock.sleep(YIELD_POLL_S)

    # ------------------------------------------------------------------ plant thread

    def run(self) -> None:
        """The plant thread's loop, until :meth:`close`."""
        try:
            self.begin()
            while not self._quit.is_set():
                self._wake.clear()
                timeout = self.poll()
                if timeout > 0.0:
                    self._clock.wait(self._wake, timeout)
        except Exception as exc:  # noqa: BLE001
            if self._host_ok() and not self._quit.is_set():
                self._log.fatal(f"plant thread stopped: {type(exc).__name__}: {exc}")
                self.exit_status = 1
                self.finished.set()
            # else: the host was shut down under us (SIGINT/SIGTERM); it cleans up

    def begin(self) -> None:
        """Publish the initial state and start the schedule (first of the plant thread)."""
        now = self._clock.monotonic()
        self._publish(self.sim.snapshot())
        self._restart_schedule(now)
        self._window.restart(now)
        self._next_status_wall = now + DIAGNOSTICS_PERIOD_S

    def poll(self) -> float:
        """Run the queued jobs, flush, report and advance a chunk if one is due.

        Returns
        -------
        float
            Wall time until something is due [s]; 0 after a chunk.
        """
        self._run_jobs()
        if self.recorder is not None:
            self.recorder.flush_if_due()
        now = self._maybe_report()
        timeout = self._next_status_wall - now
        if self._free_running():
            due = self._due()
            if due <= now:
                self._paced_chunk(due)
                return 0.0
            timeout = min(timeout, due - now)
        if self.recorder is not None:
            # idle (paused, lock-step, slow pace): still flush within the interval
            timeout = min(timeout, self.recorder.seconds_until_flush())
        return max(timeout, 0.0)

    def _status(self, now: float) -> PlantStatus:
        # the diagnostics report at wall time ``now``; starts the next pace window
        sim, stats = self.sim, self.stats
        achieved, new, window_s = self._window.take(now, sim.time_s, stats.overruns)
        if self.failure:
            state, reason = "failed", self.failure
        elif self.finished.is_set():
            state, reason = "finished", self.finish_reason
        else:
            state = "following" if self.settings.follow_clock else \
                "lockstep" if self.settings.lockstep else \
                "paused" if self.paused else "running"
            reason = ""
        rec = self.recorder
        return plant_status(
            sim, state=state, reason=reason, achieved=achieved, window_s=window_s,
            new_overruns=new, chunks=stats.chunks, overruns=stats.overruns,
            dropped_s=stats.dropped_s,
            lag_s=self._lag(now), peak_lag_s=self._window.take_peak_lag(),
            real_time_factor=self.real_time_factor, commands=self.commands,
            rejected=sum(self.rejected.values()), new_rejected=self._window.take_rejected(
                sum(self.rejected.values())), handled=self.handled, resets=self.resets,
            recording="off" if rec is None else rec.state,
            recording_error=None if rec is None else rec.error)

    def _run_jobs(self, jobs: queue.SimpleQueue | None = None) -> None:
        # only the jobs queued so far: a flood of inputs must not starve the chunks; the
        # urgent ones first
        if jobs is None:
            self._run_jobs(self._urgent)
            jobs = self._jobs
        for _ in range(jobs.qsize()):
            try:
                job = jobs.get_nowait()
            except queue.Empty:
                return
            job.run(self._log.error if self._host_ok() else None)

    def _maybe_report(self) -> float:
        # every wall period; and every simulated period when the wall clock does not pace
        # the plant, so that its recording holds reports by simulated time at any speed
        now = self._clock.monotonic()
        s = self.settings
        if now >= self._next_status_wall or (
                (self.real_time_factor <= 0.0 or s.lockstep or s.follow_clock)
                and self.sim.time_s >= self._next_status_sim - TIME_EPS_S):
            self._report(now)
        return now

    def _report(self, now: float) -> None:
        self._next_status_wall = now + DIAGNOSTICS_PERIOD_S
        period = DIAGNOSTICS_SIM_PERIOD_S
        self._next_status_sim = (math.floor(self.sim.time_s / period + TIME_EPS_S) + 1) * period
        self._publish_status(self._status(now))

    def _free_running(self) -> bool:
        s = self.settings
        return not (s.lockstep or s.follow_clock or self.paused or self.failure
                    or self.finished.is_set())

    def _lag(self, now: float) -> float:
        """How far a paced plant is behind its schedule at ``now``, 0 if not [s wall]."""
        if self.real_time_factor <= 0.0 or not self._free_running():
            return 0.0
        return max(now - self._due(), 0.0)

    def _due(self) -> float:
        """Wall deadline of the next chunk [s] (``-inf`` as fast as possible)."""
        return self._pacer.due_at(self._next_index * self.settings.chunk_s)

    def _restart_schedule(self, now: float, first_due_now: bool = False) -> None:
        # the next chunk is due one period from now (or at once), later ones follow at the period
        self._pacer.rebase(0.0, now)
        self._next_index = 0 if first_due_now else 1
        self._last_chunk_end = now

    def _paced_chunk(self, due: float) -> None:
        self._run_chunk(self._publish_due())
        done = self._clock.monotonic()
        if self.real_time_factor <= 0.0:
            # let a receiving thread take the GIL now and then (see GIL_YIELD_PERIOD_S)
            self._gil_held_s += done - self._last_chunk_end - self.advance_wall_s
            self._last_chunk_end = done
            if self._gil_held_s >= GIL_YIELD_PERIOD_S:
                self._gil_held_s = 0.0
                self._clock.sleep(0)
                self._last_chunk_end = self._clock.monotonic()
            return
        stats = self.stats
        stats.lateness_s.append(done - due)
        self._next_index += 1
        lag = done - self._due()
        if lag > 0.0:
            stats.max_lag_s = max(stats.max_lag_s, lag)
            self._window.lag(lag)
            if lag <= self.settings.max_catch_up_s:
                # the next chunks are due already: poll runs them at once until on schedule
                stats.caught_up += 1
            else:
                # too far behind to catch up: count it and restart the schedule from now
                stats.overruns += 1
                stats.dropped_s += lag
                self._restart_schedule(done, first_due_now=True)

    def _publish(self, snap: Snapshot) -> None:
        self.stamp_ns = round(snap.time_s * 1e9)
        self._publish_state(snap)

    def _publish_due(self) -> bool:
        """Whether the chunk about to run is one ``publish_every`` publishes."""
        return (self.run_chunks + 1) % self.settings.publish_every == 0

    def _run_chunk(self, publish: bool = True) -> bool:
        """Advance one chunk and publish its state if ``publish``; False if the simulator
        failed."""
        sim, s = self.sim, self.settings
        if 0.0 <= s.auto_brake_at_s <= sim.time_s + TIME_EPS_S and not self._auto_brake_done:
            self._auto_brake_done = True
            self._on_input("emergency", True, None)
        start = self._clock.monotonic()
        try:
            snap = sim.advance(s.chunk_s, self.commands)
        except SimulationError as exc:
            self._fail(str(exc))
            return False
        except Exception as exc:  # noqa: BLE001 - any simulator fault stops the plant, not the host
            self._fail(f"{type(exc).__name__}: {exc}")
            return False
        self.advance_wall_s = self._clock.monotonic() - start
        self.stats.chunks += 1
        self.run_chunks += 1
        if publish:
            self._publish(snap)
        else:
            self.stamp_ns = round(snap.time_s * 1e9)
        log = self._log
        for event in snap.events:
            if event.kind == "limit_exceeded":
                self._log_limit(event)
            elif event.kind != "coupler_out_of_lut":
                log.info(event.describe())
            elif self._lut_warned:
                log.debug(event.describe())
            else:
                # long trains push dozens of couplers past the table: warn once per run
                self._lut_warned = True
                log.warning(f"{event.describe()}; further couplers are logged at debug level "
                            "and counted in diagnostics")
        if 0.0 <= s.max_sim_time_s <= snap.time_s + TIME_EPS_S:
            log.info(f"max_sim_time_s = {s.max_sim_time_s:g} s reached; shutting down")
            self._finish("max_sim_time_s reached")
        if sim.stop_time_s is not None and \
                0.0 <= s.shutdown_after_stop_s <= snap.time_s - sim.stop_time_s + TIME_EPS_S:
            log.info(f"{s.shutdown_after_stop_s:g} s after the stop; shutting down")
            self._finish("shutdown_after_stop_s reached")
        return True

    def _log_limit(self, event) -> None:
        """One line per criterion and run at WARN (ERROR for a force beyond a strength); every
        further coupler or vehicle beyond the same limit at DEBUG, all of them counted in
        /diagnostics (``verdict_<criterion>``)."""
        name = event.detail.get("criterion", "")
        if name in self._limits_logged:
            self._log.debug(event.describe())
            return
        self._limits_logged.add(name)
        text = (f"{event.describe()}; further couplers or vehicles beyond this limit are logged "
                f"at debug level and counted in /diagnostics (verdict_{name})")
        if name in ("draft_strength", "buff_strength", "coupler_travel"):
            self._log.error(text)
        else:
            self._log.warning(text)

    def _finish(self, reason: str) -> None:
        self.finish_reason = reason
        self.finished.set()

    def _fail(self, reason: str) -> None:
        self.failure = reason
        self._log.error(f"simulation failed at t = {self.sim.time_s:.3f} s: {reason}; "
                        "the plant stopped advancing, call ~/reset to recover")
        self._report(self._clock.monotonic())
        # the run is over: finish its bag (ending with the ERROR above) so that it is complete
        # and readable now, not only once the host exits; a reset starts the next one
        self._end_run()
        if self.recorder is not None:
            self.recorder.close()

    def _on_input(self, name: str, value: Any, message: Any) -> None:
        self.handled += 1
        self._input_handled(name, value, message)
        if name == "emergency":
            # held until changed; the simulator ignores a repeated true
            self.commands = replace(self.commands, emergency=bool(value))
            return
        if name == "driver_brake_valve":
            change = valve_position(value)
            if change is not None:
                self.commands = replace(self.commands, **change)
                return
            self._reject(name, f"rejected {value!r}, expected a position of the driver's brake "
                         f"valve: {', '.join(VALVE_POSITIONS)}; keeping the previous commands")
            return
        lo, hi = COMMAND_RANGES[name]
        if lo <= value <= hi:  # NaN and infinities fail the comparison
            self.commands = replace(self.commands, **{name: float(value)})
            return
        self._reject(name, f"rejected {value!r}, expected a finite number from {lo:g} to "
                     f"{hi:g}; keeping the previous value")

    def _reject(self, name: str, text: str) -> None:
        # counted, logged at most every REJECT_LOG_PERIOD_S per input; the old value is kept
        self.rejected[name] = self.rejected.get(name, 0) + 1
        now = self._clock.monotonic()
        if now >= self._next_reject_log.get(name, 0.0):
            self._next_reject_log[name] = now + REJECT_LOG_PERIOD_S
            self._log.warning(f"{self._labels.get(name, name)}: {text} "
                              f"({self.rejected[name]} rejected so far)")

    def _end_run(self) -> None:
        """Publish (and record) how the run ends, once; never raises."""
        if self._publish_end is None or self._ended_run == self.resets:
            return
        self._ended_run = self.resets
        try:
            events = self.sim.end_events()
            if events:
                self._publish_end(events)
        except Exception as exc:  # noqa: BLE001 - the run's end must not stop a reset or close
            self._log.warning(f"the run's last stop was not published: {exc}")

    def _reset(self, replacement=None, recording_of_run=None, hold=False) -> tuple[bool, str]:
        rec, recording = self.recorder, ""
        self._end_run()
        if rec is not None:
            # one run per bag (the report assumes it): the next run's bag is opened first, so
            # a reset that could not be recorded does not happen (never a success while the
            # recording has stopped); then the current bag is finished
            current = rec.state
            try:
                rec.reopen(*(recording_of_run or ()))
            except StartupError as exc:
                goes_on = f"recording to {current}" if rec.active else "without recording"
                text = f"not reset: {exc.reason}; the run goes on {goes_on}"
                self._log.error(text)
                return False, text
            recording = f"; recording to {rec.state}"
        if replacement is not None:
            sim, settings = replacement
            s = self.settings
            self.sim = sim
            self.settings = replace(settings, chunk_s=s.chunk_s, lockstep=s.lockstep,
                                    follow_clock=s.follow_clock, publish_every=s.publish_every,
                                    real_time_factor=self.real_time_factor)
        snap = self.sim.reset()
        self.resets += 1
        self.run_chunks = 0
        self.clock_backs = 0
        self._next_clock_back_log = 0.0
        self._catching_up = False
        self.commands = Commands()
        self._auto_brake_done = False
        self._lut_warned = False
        self._limits_logged = set()
        self.failure = None
        self._next_status_sim = DIAGNOSTICS_SIM_PERIOD_S
        self._publish(snap)
        now = self._clock.monotonic()
        self._restart_schedule(now)
        self._window.restart(now, 0.0)
        self.stopped = False
        if hold:
            self.paused = self.stopped = True
            self._log.info("stopped: initial state, brake released, t = 0 s, holding")
            return True, (f"stopped: reset to the initial state (brake released, t = 0 s), "
                          f"holding until played or paused{recording}")
        self._log.info("reset: initial state, brake released, t = 0 s")
        return True, f"reset to the initial state (brake released, t = 0 s){recording}"

    def _pause(self, pause: bool) -> tuple[bool, str]:
        if self.settings.follow_clock:
            return False, FOLLOWING
        if self.paused and not pause:
            self._restart_schedule(self._clock.monotonic())
            self.stopped = False
        self.paused = pause
        text = f"{'paused' if pause else 'running'} at t = {self.sim.time_s:.3f} s"
        if self.settings.lockstep:
            text += (" (lock-step mode: ~/step is refused until ~/pause false)" if pause else
                     " (lock-step mode: the plant advances only on ~/step)")
        return True, text

    def _step(self, chunks: int) -> tuple[bool, str]:
        if self.settings.follow_clock:
            return False, FOLLOWING
        if not (self.settings.lockstep or self.paused):
            return False, "the plant is free-running: pause it (~/pause) or start it with " \
                          "lockstep:=true to step it"
        if self.settings.lockstep and self.paused:
            # a paused lock-step plant holds: a controller's steps do not carry it on
            return False, (f"paused at t = {self.sim.time_s:.3f} s: ~/step is refused until "
                           "~/pause false")
        if self.failure:
            return False, f"simulation failed: {self.failure}; call ~/reset"
        if self.finished.is_set():
            return False, "max_sim_time_s reached; the node is shutting down"
        if chunks < 1:
            return False, f"a step is at least 1 chunk, got {chunks}"
        self.stopped = False
        done, stopped_by = 0, ""
        while done < chunks:
            # the last chunk of a request is always published: it answers the request
            if not self._run_chunk(done + 1 == chunks or self._publish_due()):
                return False, f"simulation failed: {self.failure}; call ~/reset"
            done += 1
            self._maybe_report()
            if self.finished.is_set():  # a run limit: the step ends with the run
                break
            if done < chunks:
                stopped_by = self._between_step_chunks()
                if stopped_by:
                    break
        c = self.commands
        # the inputs the chunks ran with (exact values), so a controller can check that its
        # last command was in the step
        text = (f"advanced {done} chunk(s) to t = {self.sim.time_s:.3f} s with "
                f"emergency={str(c.emergency).lower()} "
                f"brake_demand={c.brake_demand!r} traction={c.traction!r} "
                f"overcharge={str(c.overcharge).lower()} "
                f"(inputs handled: {self.handled})")
        if stopped_by:
            return False, f"{stopped_by} after {done} of {chunks} chunks: {text}"
        return True, text

    def _between_step_chunks(self) -> str:
        """Serve the urgent requests and the recorder between two chunks of a step; why the
        step ends here, or empty."""
        if self.recorder is not None:
            self.recorder.flush_if_due()
        self._run_jobs(self._urgent)
        if self._quit.is_set():
            return "interrupted by shutdown"
        if self.finished.is_set():
            return f"interrupted: {self.finish_reason}"
        if self.settings.lockstep and self.paused:
            return "interrupted by a pause"
        if not self.settings.lockstep and not self.paused:
            return "interrupted: the plant was resumed"
        return ""

    def _set_state(self, target: str) -> tuple[str, str]:
        state, _ = self.simulation_state()
        s = self.settings
        if target == QUITTING:
            if state == QUITTING:
                return "already", "the run has ended; the node is shutting down"
            self._log.info("quitting on request: shutting down")
            self._finish("quit on request")
            return "ok", "the run ends; the node shuts down"
        if target not in (PLAYING, PAUSED):
            return "refused", f"no such state here: {target!r}"
        if state == QUITTING:
            return "refused", f"the run has ended ({self.finish_reason}); the node is shutting down"
        if s.follow_clock:
            return "refused", FOLLOWING
        if self.failure:
            return "failed", f"simulation failed: {self.failure}; reset it"
        if target == PLAYING:
            if s.lockstep:
                return "refused", ("a lock-step plant (lockstep:=true) advances only when "
                                   "stepped; start it with lockstep:=false to play it")
            if state == PLAYING:
                return "already", f"playing at t = {self.sim.time_s:.3f} s"
            return "ok", self._pause(False)[1]
        # PAUSED: a free-running plant holds; a held lock-step plant may be stepped again
        if state == PAUSED and not (s.lockstep and self.paused):
            return "already", f"paused at t = {self.sim.time_s:.3f} s"
        self.stopped = False
        return "ok", self._pause(not s.lockstep)[1]

    def _follow(self) -> None:
        # advance whole chunks up to the followed clock's latest time
        self._follow_pending = False
        target = self.follow_target_s
        if target is None or self.failure or self.finished.is_set():
            return
        sim, chunk_s = self.sim, self.settings.chunk_s
        if target < sim.time_s - chunk_s - TIME_EPS_S:
            # logged at most every REJECT_LOG_PERIOD_S: two sources of the clock alternate
            self.clock_backs += 1
            now = self._clock.monotonic()
            if now >= self._next_clock_back_log:
                self._next_clock_back_log = now + REJECT_LOG_PERIOD_S
                self._log.warning(
                    f"the followed clock went back to t = {format_fixed(target)} s (its "
                    f"source was reset, or a second node publishes it?); this train holds at "
                    f"t = {format_fixed(sim.time_s)} s until the clock passes it again "
                    f"(~/reset starts it from t = 0; {self.clock_backs} time(s) so far)")
            return
        gap = target - sim.time_s
        if gap > FOLLOW_JUMP_S and not self._catching_up:
            self._catching_up = True
            self._log.warning(
                f"the followed clock jumped ahead to t = {format_fixed(target)} s, "
                f"{format_fixed(gap)} s beyond this train (t = {format_fixed(sim.time_s)} s): "
                f"catching up as fast as it runs, in slices of {FOLLOW_SLICE_S * 1e3:g} ms "
                "that leave services and shutdown answered")
        monotonic = self._clock.monotonic
        end = monotonic() + FOLLOW_SLICE_S
        while sim.time_s + chunk_s <= target + TIME_EPS_S and not self.finished.is_set():
            if self._quit.is_set():
                return
            if monotonic() >= end:  # serve what is queued, then go on from here
                if not self._follow_pending:
                    self._follow_pending = True
                    self.submit(self._follow)
                return
            last = sim.time_s + 2.0 * chunk_s > target + TIME_EPS_S
            if not self._run_chunk(last or self._publish_due()):
                return
            self._maybe_report()
        if self._catching_up:
            self._catching_up = False
            self._log.info(f"caught up with the followed clock at t = "
                           f"{format_fixed(sim.time_s)} s")

    def _set_real_time_factor(self, value: float) -> None:
        now = self._clock.monotonic()
        self.real_time_factor = float(value)
        self._pacer.set_rate(self.real_time_factor, now)
        self._restart_schedule(now)
        self._log.info(f"real_time_factor set to {value:g}")
