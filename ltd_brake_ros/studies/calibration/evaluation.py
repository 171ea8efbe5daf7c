"""Evaluating the targets: the trains' emergency stops, on one process pool for a whole fit."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ...inputs import BrakeParams, Consist, CouplerLUT, InputError
from ...physics import couplers
from ...physics.parameters import CompileError
from ..parallel import default_workers, process_pool
from .parameters import coupler_fit_parameters, fit_parameters


#: What one emergency stop yields for the fits, in this order: stopping distance [m], peak
#: draft force [kN] and its coupler, peak buff force magnitude [kN] and its coupler.
METRICS = ("stopping_distance_m", "peak_draft_kN", "peak_draft_coupler", "peak_buff_kN",
           "peak_buff_coupler")
DISTANCE, DRAFT, DRAFT_AT, BUFF, BUFF_AT = range(len(METRICS))

# Per-worker state, set once by the pool initializer, so that tasks carry only parameters.
_CASES: list[tuple[Consist, float]] = []
_LUT: CouplerLUT | None = None
_STEP_S = 0.01


def _init_worker(cases, lut, step_s) -> None:
    global _CASES, _LUT, _STEP_S
    _CASES, _LUT, _STEP_S = list(cases), lut, step_s


def _describe(params: BrakeParams, lut) -> str:
    """The fittable values of a trial point, for a failure message."""
    values = [f"{p.field}={getattr(params, p.field):.6g}"
              for p in fit_parameters(params.model).values()]
    if lut is not None:
        values += [f"{p.field}={getattr(lut, p.field):.6g}"
                   for p in coupler_fit_parameters(couplers.model_of(lut).NAME).values()]
    return ", ".join(values)


def _run_chunk(chunk) -> list[tuple[tuple, str | None]]:
    from ..runs import emergency_stop
    from ...simulator import SimulationError

    out = []
    for params, lut, i in chunk:
        consist, speed = _CASES[i]
        try:
            r = emergency_stop(consist, speed, params, lut or _LUT, step_s=_STEP_S)
            out.append(((r.stopping_distance_m, r.peak_draft_kN, r.peak_draft_coupler,
                         -r.peak_buff_kN, r.peak_buff_coupler), None))
        except (SimulationError, CompileError, InputError) as exc:
            # a trial point the integrator cannot handle, or parameters that make no coupling
            # (a reshaped table beyond its bounds): the optimiser rejects it. Only the message
            # goes back, so that any exception reaches the parent process.
            out.append(((math.nan,) * len(METRICS),
                        f"{consist.name} from {speed:g} km/h with "
                        f"{_describe(params, lut)}: {exc}"))
    return out


class DistanceEvaluator:
    """Emergency stops of a fixed set of trains for many parameter sets, on one pool.

    Parameters
    ----------
    cases : sequence of (Consist, float)
        Trains and initial speeds [km/h].
    lut : CouplerLUT
        Coupler parameters of the runs that name none.
    step_s : float, optional
        Integration step [s].
    workers : int, optional
        Processes (default: every core); 1 runs in this process.
    progress : tqdm.tqdm, optional
        Advanced by one per emergency stop.

    Notes
    -----
    Use as a context manager so that the pool is shut down.
    """

    def __init__(self, cases: Sequence[tuple[Consist, float]], lut: CouplerLUT, *,
                 step_s: float = 0.01, workers: int | None = None, progress=None):
        self.cases = list(cases)
        self.lut, self.step_s = lut, step_s
        self.workers = max(1, int(workers or default_workers()))
        self.progress = progress
        self.runs = 0
        #: Messages of the emergency stops that failed (their metrics are NaN).
        self.failures: list[str] = []
        # cost of one stop ~ vehicles x speed (steps to standstill x kernel cost per step)
        self._cost = [c.n * s for c, s in self.cases]
        self._pool = None
        if self.workers > 1:
            self._pool = process_pool(self.workers, initializer=_init_worker,
                                      initargs=(self.cases, lut, step_s))
        else:
            _init_worker(self.cases, lut, step_s)

    def __enter__(self) -> "DistanceEvaluator":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Shut the pool down."""
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None

    def distances(self, param_sets: Sequence[BrakeParams],
                  cases: Sequence[int] | None = None) -> np.ndarray:
        """Stopping distances of every case for every brake-parameter set.

        Parameters
        ----------
        param_sets : sequence of BrakeParams
        cases : sequence of int, optional
            Indices into the evaluator's cases (default: all).

        Returns
        -------
        ndarray, shape (len(param_sets), len(cases))
            Stopping distances [m]; NaN where the simulation failed (see ``failures``).
        """
        return self.metrics([(p, None) for p in param_sets], cases)[:, :, DISTANCE]

    def metrics(self, models: Sequence[tuple[BrakeParams, object]],
                cases: Sequence[int] | None = None) -> np.ndarray:
        """:data:`METRICS` of every case for every pair of brake and coupler parameters.

        Parameters
        ----------
        models : sequence of (BrakeParams, coupler Params or None)
            None: the evaluator's coupler parameters.
        cases : sequence of int, optional
            Indices into the evaluator's cases (default: all).

        Returns
        -------
        ndarray, shape (len(models), len(cases), len(METRICS))
            NaN where the simulation failed (see ``failures``).
        """
        idx = list(range(len(self.cases))) if cases is None else list(cases)
        jobs = [(a, b) for a in range(len(models)) for b in range(len(idx))]
        out = np.empty((len(models), len(idx), len(METRICS)))
        for chunk, values in self._run(jobs, models, idx):
            for (a, b), (v, err) in zip(chunk, values):
                out[a, b] = v
                if err:
                    self.failures.append(err)
        return out

    def _run(self, jobs, models, idx):
        def payload(chunk):
            return [(*models[a], idx[b]) for a, b in chunk]

        if self._pool is None:
            for job in jobs:
                values = _run_chunk(payload([job]))
                self._advance(1)
                yield [job], values
            return
        # a few chunks per worker, balanced by cost (longest first), so that both the
        # scheduling overhead and the idle tail at the end of a batch stay small
        n_chunks = min(len(jobs), 3 * self.workers)
        chunks: list[list] = [[] for _ in range(n_chunks)]
        load = [0.0] * n_chunks
        for job in sorted(jobs, key=lambda j: -self._cost[idx[j[1]]]):
            k = load.index(min(load))
            chunks[k].append(job)
            load[k] += self._cost[idx[job[1]]]
        from concurrent.futures import as_completed

        futures = {self._pool.submit(_run_chunk, payload(c)): c for c in chunks if c}
        for fut in as_completed(futures):
            chunk = futures[fut]
            values = fut.result()
            self._advance(len(chunk))
            yield chunk, values

    def _advance(self, n: int) -> None:
        self.runs += n
        if self.progress is not None:
            self.progress.update(n)
