"""The model-form band of a stop: the same stop under every credible pair of models.

No single model of a freight train's brake or couplers is validated beyond the paper's trains;
their differences are the part of the answer a model cannot give. A band runs the stop of
:func:`~ltd_brake_ros.studies.runs.emergency_run` once per member, every brake model of a band
file (:func:`~ltd_brake_ros.inputs.band.load_band`) with every coupler model, tags each member
inside or outside its models' ranges (:func:`~ltd_brake_ros.inputs.model_warnings`), and
reports each key number as the nominal member's value with the band's lowest and highest and
the members that gave them:

* the band's verdict counts the members inside their ranges only: PASS (or WARN) when every
  one passes, FAIL when every one fails, ``model-dependent`` where they disagree;
* a member marked NON-PHYSICAL (a coupling beyond its buffers' limit state or travel) makes
  the band NON-PHYSICAL, inside its range or not;
* with no member inside its range the band gives no verdict and says so.

The nominal member is the run's own models (the train's default brake model and the shipped
coupler table, or those given).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from ..inputs import default_brake_params, load_coupler_lut
from ..inputs.band import ModelFormBand, load_band
from ..physics.kernel import DEFAULT_TOLERANCE_M_S
from .runs import emergency_run

__all__ = ["BAND_KPIS", "BandKPI", "BandResult", "MemberResult", "contains_paper", "run_band",
           "tables_coverage"]

#: The key numbers of a band: attribute of :class:`MemberResult` -> (label, unit).
BAND_KPIS = {"stopping_distance_m": ("stopping distance", "m"),
             "peak_draft_kN": ("peak draft", "kN"),
             "peak_buff_kN": ("peak buff", "kN")}


@dataclass(frozen=True)
class MemberResult:
    """One member's stop.

    Attributes
    ----------
    brake, coupler : str
        The member's models, as the band file names them.
    in_range : bool
        Both models are within their validated ranges for this train.
    warnings : tuple of str
        Where they are not (:func:`~ltd_brake_ros.inputs.model_warnings`).
    stopping_distance_m : float
        The head's travel from the command to the standstill [m].
    peak_draft_kN, peak_buff_kN : float
        Largest draft (positive) and buff (negative) force, command to standstill [kN].
    peak_draft_coupler, peak_buff_coupler : int
        Their couplers, from 1 behind the head.
    status : str
        The member's verdicts: ``PASS``, ``WARN`` or ``FAIL``.
    non_physical : str or None
        The run's non-physical line (None: physical).
    cpu_s : float
        CPU time of the member's run [s].
    """

    brake: str
    coupler: str
    in_range: bool
    warnings: tuple
    stopping_distance_m: float
    peak_draft_kN: float
    peak_draft_coupler: int
    peak_buff_kN: float
    peak_buff_coupler: int
    status: str
    non_physical: str | None
    cpu_s: float

    @property
    def name(self) -> str:
        """``brake + coupler``."""
        return f"{self.brake} + {self.coupler}"


@dataclass(frozen=True)
class BandKPI:
    """One key number over the band.

    Attributes
    ----------
    name : str
        A key of :data:`BAND_KPIS`.
    nominal : float
        The nominal member's value.
    low, high : float
        The band's lowest and highest value (by magnitude for the buff force).
    low_member, high_member : str
        The members that gave them.
    """

    name: str
    nominal: float
    low: float
    high: float
    low_member: str
    high_member: str

    def contains(self, value: float, tolerance: float = 0.0) -> bool:
        """``value`` lies within [low, high] (widened by ``tolerance`` of each end)."""
        lo, hi = sorted((self.low, self.high))
        return lo - tolerance * abs(lo) <= value <= hi + tolerance * abs(hi)


@dataclass(frozen=True)
class BandResult:
    """A stop under every member of a model-form band.

    Attributes
    ----------
    band : str
        The band's name and file.
    members : tuple of MemberResult
    nominal : int
        Index of the nominal member.
    kpis : dict of str to BandKPI
        :data:`BAND_KPIS` over every member.
    status : str
        ``PASS``, ``WARN``, ``FAIL``, ``model-dependent``, ``NON-PHYSICAL`` or ``no member in
        range`` (see the module).
    cpu_s : float
        CPU time of the whole band [s].
    """

    band: str
    members: tuple
    nominal: int
    kpis: dict = field(default_factory=dict)
    status: str = ""
    cpu_s: float = 0.0

    @property
    def in_range(self) -> tuple:
        """The members inside their models' ranges."""
        return tuple(m for m in self.members if m.in_range)

    def describe(self) -> list[str]:
        """The band as text lines: its verdict, each key number, each member."""
        n_in = len(self.in_range)
        lines = [f"band             {self.status} ({n_in} of {len(self.members)} members "
                 f"inside their models' ranges; {self.band})"]
        for name, k in self.kpis.items():
            label, unit = BAND_KPIS[name]
            mag = abs if name == "peak_buff_kN" else float
            lines.append(f"  {label:<18} {mag(k.nominal):.1f} {unit} [{mag(k.low):.1f}, "
                         f"{mag(k.high):.1f}] (low: {k.low_member}; high: {k.high_member})")
        for i, m in enumerate(self.members):
            tag = "nominal, " if i == self.nominal else ""
            tag += "inside its range" if m.in_range else "OUTSIDE its range"
            lines.append(f"  member {m.name} ({tag}): {m.stopping_distance_m:.1f} m, draft "
                         f"{m.peak_draft_kN:.0f} kN at coupler {m.peak_draft_coupler}, buff "
                         f"{-m.peak_buff_kN:.0f} kN at coupler {m.peak_buff_coupler}; "
                         f"{m.status}" + (" NON-PHYSICAL" if m.non_physical else ""))
        return lines

    def as_dict(self) -> dict:
        """JSON-serialisable, units in the keys."""
        return {"band": self.band, "status": self.status, "nominal": self.nominal,
                "cpu_s": self.cpu_s,
                "kpis": {k: {"nominal": v.nominal, "min": v.low, "max": v.high,
                             "min_member": v.low_member, "max_member": v.high_member}
                         for k, v in self.kpis.items()},
                "members": [dict(m.__dict__, name=m.name, warnings=list(m.warnings))
                            for m in self.members]}


def _verdict(members) -> str:
    """The band's verdict (see the module)."""
    if any(m.non_physical for m in members):
        return "NON-PHYSICAL"
    inside = [m for m in members if m.in_range]
    if not inside:
        return "no member in range"
    statuses = {m.status for m in inside}
    if statuses == {"FAIL"}:
        return "FAIL"
    if "FAIL" in statuses:
        return "model-dependent"
    return "WARN" if "WARN" in statuses else "PASS"


def _kpi(name: str, members, nominal: int) -> BandKPI:
    key = (lambda m: -getattr(m, name)) if name == "peak_buff_kN" else \
        (lambda m: getattr(m, name))
    lo, hi = min(members, key=key), max(members, key=key)

    def named(m):
        return m.name + ("" if m.in_range else " (outside its range)")
    return BandKPI(name, getattr(members[nominal], name), getattr(lo, name), getattr(hi, name),
                   named(lo), named(hi))


def run_band(consist, speed_kmh: float, params=None, lut=None, track=None, *,
             band: ModelFormBand | None = None, step_s: float = 0.01,
             tolerance_m_s: float | None = DEFAULT_TOLERANCE_M_S, chunk_s: float = 1.0,
             max_time_s: float = 600.0, on_nominal=None,
             on_nominal_start=None) -> tuple[BandResult, object]:
    """An emergency stop under every member of a model-form band.

    Parameters
    ----------
    consist : Consist
    speed_kmh : float
        Initial speed [km/h].
    params, lut : optional
        The run's own models: the nominal member (default: the train's default brake model,
        :func:`~ltd_brake_ros.inputs.default_brake_params`, and the shipped coupler table).
        Added to the band when it holds neither.
    track : Track, optional
    band : ModelFormBand, optional
        The members (default: the shipped ``bands/model_form.yaml``).
    step_s, tolerance_m_s, chunk_s, max_time_s : optional
        As for :func:`~ltd_brake_ros.studies.runs.emergency_run`.
    on_nominal : callable, optional
        Called with each snapshot of the nominal member's run (chunk by chunk).
    on_nominal_start : callable, optional
        Called with the nominal member's simulator before its first chunk.

    Returns
    -------
    BandResult
    Simulator
        The nominal member's, at the end of its run.
    """
    band = band or load_band()
    params = params or default_brake_params(consist)
    lut = lut or load_coupler_lut()
    brakes = [(m.name, m.params) for m in band.brake]
    if not any(_same(p, params) for _, p in brakes):
        brakes.insert(0, (f"the run's ({params.model})", params))
    couplers = [(m.name, m.params) for m in band.coupler]
    if not any(p == lut for _, p in couplers):
        couplers.insert(0, ("the run's coupler", lut))
    members, nominal, nominal_sim = [], 0, None
    start = time.process_time()
    for bname, bparams in brakes:
        for cname, cparams in couplers:
            is_nominal = _same(bparams, params) and cparams == lut
            t0 = time.process_time()
            sim = emergency_run(consist, speed_kmh, bparams, cparams, track, step_s=step_s,
                                tolerance_m_s=tolerance_m_s, chunk_s=chunk_s,
                                max_time_s=max_time_s, group=not (is_nominal and on_nominal),
                                on_chunk=on_nominal if is_nominal else None,
                                on_start=on_nominal_start if is_nominal else None)
            peaks, table = sim.stop_peaks, sim.verdicts()
            if is_nominal:
                nominal, nominal_sim = len(members), sim
            members.append(MemberResult(
                bname, cname, not sim.model_warnings, tuple(sim.model_warnings),
                float(sim.stopping_distance_m), peaks.draft_N / 1e3, peaks.draft_coupler,
                peaks.buff_N / 1e3, peaks.buff_coupler, table.status, table.non_physical_line,
                time.process_time() - t0))
    kpis = {name: _kpi(name, members, nominal) for name in BAND_KPIS}
    return (BandResult(f"{band.name} ({band.source})", tuple(members), nominal, kpis,
                       _verdict(members), time.process_time() - start), nominal_sim)


def _same(a, b) -> bool:
    """The same brake parameters (their models' values, wherever they were read from)."""
    return a.pneumatic == b.pneumatic and a.friction == b.friction and a.thermal == b.thermal


def contains_paper(result: BandResult, paper: dict) -> dict:
    """Whether the band contains each of the paper's values of a run of Tables 1-2.

    Parameters
    ----------
    result : BandResult
    paper : dict
        The scenario's published values (``ltdpolito_m``, ``draft_kN``, ``buff_kN``).

    Returns
    -------
    dict of str to bool
    """
    values = {"stopping_distance_m": paper["ltdpolito_m"], "peak_draft_kN": paper["draft_kN"],
              "peak_buff_kN": -paper["buff_kN"]}
    return {k: result.kpis[k].contains(v) for k, v in values.items()
            if math.isfinite(v)}


def tables_coverage(band: ModelFormBand | None = None, scenarios: list[int] | None = None, *,
                    step_s: float = 0.01, workers: int = 1) -> list[tuple]:
    """The band of each run of the paper's Tables 1-2, and whether it holds the paper's values.

    A figure, not a target: no member is added or tuned for it.

    Parameters
    ----------
    band : ModelFormBand, optional
        The members (default: the shipped band).
    scenarios : list of int, optional
        Scenario numbers (default: all 12).
    step_s : float, optional
    workers : int, optional
        Processes to run the scenarios on.

    Returns
    -------
    list of (Scenario, BandResult, dict)
        Per scenario its band and :func:`contains_paper`.
    """
    from ..inputs import load_brake_params, load_scenarios
    from .parallel import map_jobs

    band = band or load_band()
    catalogue = load_scenarios()
    chosen = [catalogue[k] for k in (scenarios or sorted(catalogue))]
    # the nominal member is the paper's method (empirical model, the paper's table)
    jobs = [(s.consist_file, s.speed_kmh, load_brake_params("brake_params/paper.yaml"), band,
             step_s) for s in chosen]
    results = map_jobs(_band_job, jobs, workers)
    return [(s, r, contains_paper(r, s.paper)) for s, r in zip(chosen, results)]


def _band_job(job) -> BandResult:
    from ..inputs import load_consist

    consist_file, speed, params, band, step_s = job
    return run_band(load_consist(consist_file), speed, params, band=band, step_s=step_s)[0]
