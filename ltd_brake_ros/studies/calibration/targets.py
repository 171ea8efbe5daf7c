"""Calibration targets: reference stopping distances (UIC 544-1, or the paper's model)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ...inputs import Consist, InputError, load_scenarios
from .parameters import UIC_C_M_PERCENT, UIC_D_M, UIC_SPEED_KMH


@dataclass(frozen=True)
class Target:
    """A train, an initial speed and the stopping distance it should reach.

    Attributes
    ----------
    label : str
        Short name in tables: the scenario number, or the consist name.
    consist : Consist
        The train.
    speed_kmh : float
        Initial speed [km/h].
    distance_m : float
        Reference stopping distance [m].
    reference : str
        Where the reference distance comes from.
    lambda_percent : float
        Braked-weight percentage of the train, Eq. 11 [%].
    scenario : int or None
        Row of Tables 1-2, if the train is one of the paper's.
    """

    label: str
    consist: Consist
    speed_kmh: float
    distance_m: float
    reference: str
    lambda_percent: float
    scenario: int | None = None


def braked_weight_percent(consist: Consist) -> float:
    """Braked-weight percentage lambda of a train, Eq. 11 [%].

    Parameters
    ----------
    consist : Consist

    Returns
    -------
    float
    """
    from ...physics import train_braked_weight_percent

    return train_braked_weight_percent([v.braked_weight_t for v in consist.vehicles],
                                       [v.mass_kg / 1e3 for v in consist.vehicles],
                                       consist.length_m)


def uic_curve_distance_m(lambda_percent: float) -> float:
    """UIC 544-1 emergency stopping distance from 100 km/h, ``S = C / lambda + D`` [m].

    Parameters
    ----------
    lambda_percent : float
        Train braked-weight percentage [%].

    Returns
    -------
    float
    """
    return UIC_C_M_PERCENT / lambda_percent + UIC_D_M


def build_targets(target: str, speed_kmh: float = UIC_SPEED_KMH,
                  scenarios: Sequence[int] | None = None,
                  consists: Sequence[Consist] = ()) -> list[Target]:
    """Select the trains to fit and their reference distances.

    Parameters
    ----------
    target : {'uic', 'paper'}
        ``uic``: UIC 544-1 (Table 1's UIC column; the curve ``S = C / lambda + D`` for the
        extra ``consists``), only at 100 km/h. ``paper``: the LTDPoliTo column of Tables 1-2.
    speed_kmh : float, optional
        Initial speed [km/h]; selects the rows of Tables 1-2.
    scenarios : sequence of int, optional
        Rows of Tables 1-2 (default: every row at ``speed_kmh``).
    consists : sequence of Consist, optional
        Further trains (``uic`` only), e.g. other lengths or braked-weight percentages that
        widen what the fit can identify.

    Returns
    -------
    list of Target

    Raises
    ------
    InputError
        Unknown target, a speed without reference values, a scenario that is unknown or at
        another speed.
    """
    if target not in ("uic", "paper"):
        raise InputError("command line", "--target", f"unknown target {target!r}; choose uic "
                         "(UIC 544-1 at 100 km/h) or paper (LTDPoliTo column of Tables 1-2)")
    if not (math.isfinite(speed_kmh) and speed_kmh > 0):
        raise InputError("command line", "--speed-kmh",
                         f"must be a positive speed, got {speed_kmh}")
    if target == "uic" and speed_kmh != UIC_SPEED_KMH:
        raise InputError("command line", "--speed-kmh", f"UIC 544-1 reference distances are "
                         f"available only at {UIC_SPEED_KMH:g} km/h (Table 1 and the curve "
                         f"S = C/lambda + D), got {speed_kmh:g} km/h")
    if target == "paper" and consists:
        raise InputError("command line", "--consist", "extra trains need --target uic: the "
                         "LTDPoliTo column exists only for the paper's trains")
    catalogue = load_scenarios()
    speeds = sorted({s.speed_kmh for s in catalogue.values()})
    if scenarios is None:
        scenarios = [k for k in sorted(catalogue) if catalogue[k].speed_kmh == speed_kmh]
        if not scenarios and not consists:
            raise InputError("command line", "--speed-kmh", f"Tables 1-2 have no run at "
                             f"{speed_kmh:g} km/h; they have {', '.join(f'{v:g}' for v in speeds)}")
    out: list[Target] = []
    for k in scenarios:
        if k not in catalogue:
            raise InputError("command line", "--scenarios", f"unknown scenario {k}; Tables 1-2 "
                             f"have {min(catalogue)}-{max(catalogue)}")
        sc = catalogue[k]
        if sc.speed_kmh != speed_kmh:
            raise InputError("command line", "--scenarios", f"scenario {k} starts at "
                             f"{sc.speed_kmh:g} km/h, not at --speed-kmh {speed_kmh:g}")
        consist = sc.consist()
        lam = braked_weight_percent(consist)
        if target == "uic":
            out.append(Target(str(k), consist, speed_kmh, float(sc.paper["uic_m"]),
                              "UIC 544-1 Table 1", lam, k))
        else:
            out.append(Target(str(k), consist, speed_kmh, float(sc.paper["ltdpolito_m"]),
                              "LTDPoliTo", lam, k))
    for consist in consists:
        lam = braked_weight_percent(consist)
        label = Path(consist.source).stem if consist.source else consist.name
        out.append(Target(label, consist, speed_kmh, uic_curve_distance_m(lam),
                          "UIC 544-1 curve C/lambda + D", lam))
    if not out:
        raise InputError("command line", "--scenarios", "no train to fit")
    return out


def companion_rows(targets: Sequence[Target]) -> list:
    """Rows of Tables 1-2 with the targets' trains at other speeds (reported, not fitted).

    Parameters
    ----------
    targets : sequence of Target

    Returns
    -------
    list of Scenario
    """
    catalogue = load_scenarios()
    used = {t.scenario for t in targets if t.scenario is not None}
    files = {catalogue[k].consist_file for k in used}
    speed = {t.speed_kmh for t in targets}
    return [s for k, s in sorted(catalogue.items())
            if k not in used and s.consist_file in files and s.speed_kmh not in speed]
