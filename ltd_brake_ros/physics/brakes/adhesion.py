"""Wheel-rail adhesion available to the brakes, and wheel slide beyond it (an option).

With an adhesion condition, each vehicle's retarding brake force is capped at the adhesion
the rail offers, mu(v) m g. A brake that asks more locks its wheelsets at the end of that step:
a locked wheelset slides, and the rail then takes only the sliding friction k mu(v) m g
(:data:`SLIDING_RATIO`, the condition's ``sliding_ratio``). It rolls again only when the
brake's static friction force, the kinetic friction law's value at rest
(:func:`.friction.retarding_force` at speed 0: Karwatzki's speed factor 0.6 for blocks, mu_eff
for discs), falls below that sliding force; at rest it no longer slides. While a wheelset
slides, its blocks do not rub on the wheel: the brake does no work and heats nothing. Without
a condition (the default) the brake force is never capped, as in the paper's method.

Conditions (each with its source and how sure it is):

* ``dry``: Curtius-Kniffler, mu = 7.5 / (V + 44) + 0.161, V in km/h (0.33 at rest, 0.21 at
  100 km/h): a traction-adhesion curve quoted by secondary sources (confidence: medium for
  a dry, clean rail);
* ``wet``: 0.6 x the dry curve (wet/dry ratio after Koffman 1948, secondary source; low);
* ``low``: 0.47 x the dry curve (0.10 at 100 km/h, 0.155 at rest), **not verified**: no
  published low-adhesion mu(v) curve was found; the level is the 0.1 below which leaf layers
  take traction (a statement, no measured curve), above the ~0.02 a laboratory measures with
  water, and the speed dependence is the dry curve's (an assumption);
* a number: the same adhesion at every speed;
* a curve: (speed, mu) points from a file (:func:`ltd_brake_ros.inputs.adhesion.load_adhesion`).

The compiled form is a table, row 0 speed [m/s] strictly increasing, row 1 mu [-],
interpolated linearly and held constant beyond its ends; an empty table switches the option off.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..equations import jit_inline, lut_segment

__all__ = ["AdhesionCondition", "CONDITIONS", "LOW_FACTOR", "OFF", "SLIDING_RATIO",
           "SLIDING_RATIO_SOURCE", "condition", "curtius_kniffler", "mu_of"]

#: Wet-rail adhesion as a fraction of dry (Koffman 1948, secondary source).
WET_FACTOR = 0.6
#: Low-adhesion curve as a fraction of dry: 0.10 at 100 km/h (not verified, see above).
LOW_FACTOR = 0.47
#: Sliding friction of a locked wheelset over the available adhesion, k [-]: Polach's A, the
#: ratio of the friction coefficient at large slip velocity to its maximum, 0.4 as Open Rails
#: codes Polach (2005) (secondary; not verified in the paper). Polach's falling friction tends
#: to the maximum as the slip velocity falls: a constant k lengthens a stop's end.
SLIDING_RATIO = 0.4
#: Where :data:`SLIDING_RATIO` comes from, as printed with it.
SLIDING_RATIO_SOURCE = ("Polach 2005's ratio at large slip velocity, as Open Rails codes it; "
                        "not verified")
#: Speeds the formula conditions are tabulated at [km/h] (every 2 km/h to 400 km/h: the
#: linear interpolation is then within 1e-4 of the formula).
_TABLE_KMH = np.arange(0.0, 402.0, 2.0)


def curtius_kniffler(speed_kmh):
    """Curtius-Kniffler's dry-rail adhesion, 7.5 / (V + 44) + 0.161 [-] (V in km/h)."""
    return 7.5 / (np.asarray(speed_kmh, float) + 44.0) + 0.161


@dataclass(frozen=True)
class AdhesionCondition:
    """An adhesion condition of the rail.

    Attributes
    ----------
    name : str
        ``dry``, ``wet``, ``constant 0.12``, a file name, or ``off``.
    table : ndarray, shape (2, k)
        Speed [m/s] and available adhesion mu [-]; k = 0: no cap (wheel slide off).
    source : str
        Where the values come from, and how sure they are.
    sliding_ratio : float
        Sliding friction of a locked wheelset over the available adhesion, k in (0, 1]
        (default :data:`SLIDING_RATIO`, not verified).
    """

    name: str
    table: np.ndarray
    source: str
    sliding_ratio: float = SLIDING_RATIO

    @property
    def on(self) -> bool:
        """Wheel slide is modelled."""
        return self.table.shape[1] > 0

    @property
    def sliding_source(self) -> str:
        """Where the sliding ratio comes from."""
        return SLIDING_RATIO_SOURCE if self.sliding_ratio == SLIDING_RATIO else "given"

    def as_dict(self) -> dict:
        """JSON-serialisable: ``adhesion`` (the name), ``adhesion_source``, ``sliding_ratio``
        and ``sliding_ratio_source`` (None when off)."""
        return {"adhesion": self.name, "adhesion_source": self.source,
                "sliding_ratio": self.sliding_ratio if self.on else None,
                "sliding_ratio_source": self.sliding_source if self.on else None}

    def __post_init__(self):
        if not 0.0 < self.sliding_ratio <= 1.0:
            raise ValueError(f"sliding_ratio {self.sliding_ratio:g} is outside (0, 1]")

    def __hash__(self) -> int:
        return hash((self.name, self.table.tobytes(), self.sliding_ratio))

    def __eq__(self, other) -> bool:
        return isinstance(other, AdhesionCondition) and self.name == other.name and \
            self.sliding_ratio == other.sliding_ratio and \
            self.table.shape == other.table.shape and bool(np.all(self.table == other.table))


def _tabulated(mu: np.ndarray) -> np.ndarray:
    return np.vstack([_TABLE_KMH / 3.6, mu]).astype(float)


#: No cap: the brake force as the brake model gives it (the paper's method).
OFF = AdhesionCondition("off", np.zeros((2, 0)), "wheel slide not modelled")
#: The named conditions.
CONDITIONS = {
    "dry": AdhesionCondition("dry", _tabulated(curtius_kniffler(_TABLE_KMH)),
                             "Curtius-Kniffler 7.5/(V+44)+0.161 (secondary sources; medium)"),
    "wet": AdhesionCondition("wet", _tabulated(WET_FACTOR * curtius_kniffler(_TABLE_KMH)),
                             "0.6 x Curtius-Kniffler (wet/dry after Koffman 1948, secondary "
                             "source; low)"),
    "low": AdhesionCondition("low", _tabulated(LOW_FACTOR * curtius_kniffler(_TABLE_KMH)),
                             "0.47 x Curtius-Kniffler, 0.10 at 100 km/h: not verified (no "
                             "published low-adhesion curve; leaf layers take traction below "
                             "0.1, the dry curve's shape assumed)"),
}


def condition(spec) -> AdhesionCondition:
    """An adhesion condition from a name, a number or a condition.

    Parameters
    ----------
    spec : None, str, float or AdhesionCondition
        None or ``off``: no cap; ``dry``, ``wet``, ``low``; a number in (0, 1]: constant
        adhesion.

    Returns
    -------
    AdhesionCondition

    Raises
    ------
    ValueError
        An unknown name or a number outside (0, 1].
    """
    if spec is None:
        return OFF
    if isinstance(spec, AdhesionCondition):
        return spec
    if isinstance(spec, str):
        key = spec.strip().lower()
        if key == "off":
            return OFF
        if key in CONDITIONS:
            return CONDITIONS[key]
        try:
            spec = float(key)
        except ValueError:
            raise ValueError(f"unknown adhesion condition {spec!r}: give dry, wet, low, off, "
                             "a number in (0, 1] or a curve file") from None
    mu = float(spec)
    if not 0.0 < mu <= 1.0:
        raise ValueError(f"adhesion {mu:g} is outside (0, 1]")
    return AdhesionCondition(f"constant {mu:g}", np.array([[0.0], [mu]]),
                             "a constant adhesion given by the user")


@jit_inline
def mu_of(table, speed_m_s):
    """Available adhesion at a speed magnitude [-] and its derivative [1/(m/s)]."""
    n = table.shape[1]
    k = lut_segment(table, speed_m_s)
    if k < 0:
        return table[1, 0], 0.0
    if k >= n - 1:
        return table[1, n - 1], 0.0
    x0, x1 = table[0, k], table[0, k + 1]
    y0, y1 = table[1, k], table[1, k + 1]
    slope = (y1 - y0) / (x1 - x0)
    return y0 + slope * (speed_m_s - x0), slope
