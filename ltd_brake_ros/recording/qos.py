"""QoS profiles as rosbag2 stores them (``offered_qos_profiles``), both ways.

The one converter between rclpy ``QoSProfile`` objects and the recorded form: dicts with string
policy names (rosbag2 metadata version 9) serialised as a YAML list. Writing needs no rclpy (a
profile is read by its attributes); :func:`qos_from_profile` imports rclpy when called.
"""
from __future__ import annotations

import yaml

_INFINITE = {"sec": 9223372036, "nsec": 854775807}
_INFINITE_NS = 9223372036 * 1_000_000_000 + 854775807
_DEFAULT_QOS = dict(history="keep_last", depth=10, reliability="reliable", durability="volatile")


def _duration(value) -> dict:
    if value is None:
        return dict(_INFINITE)
    ns = int(value.nanoseconds)
    if ns <= 0:  # rclpy's "unset" is the middleware default, which is infinite
        return dict(_INFINITE)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def qos_profiles_yaml(profile=None, **policies) -> str:
    """``offered_qos_profiles`` text (rosbag2 version 9: policy names as strings).

    Parameters
    ----------
    profile : rclpy.qos.QoSProfile, optional
        The publisher's profile. Without it the state-topic default is used: reliable,
        volatile, keep_last 10.
    **policies
        Overrides without rclpy: ``history``, ``depth``, ``reliability``, ``durability``
        (string policy names such as ``"best_effort"``).

    Returns
    -------
    str
        A YAML list holding one profile.
    """
    if profile is not None:
        p = {"history": profile.history.name.lower(), "depth": int(profile.depth),
             "reliability": profile.reliability.name.lower(),
             "durability": profile.durability.name.lower(),
             "deadline": _duration(profile.deadline), "lifespan": _duration(profile.lifespan),
             "liveliness": profile.liveliness.name.lower(),
             "liveliness_lease_duration": _duration(profile.liveliness_lease_duration),
             "avoid_ros_namespace_conventions": bool(profile.avoid_ros_namespace_conventions)}
    else:
        p = dict(_DEFAULT_QOS)
        p.update({"deadline": dict(_INFINITE), "lifespan": dict(_INFINITE),
                  "liveliness": "automatic", "liveliness_lease_duration": dict(_INFINITE),
                  "avoid_ros_namespace_conventions": False})
    for key, value in policies.items():
        if key not in ("history", "depth", "reliability", "durability", "liveliness"):
            raise TypeError(f"unknown QoS policy {key!r}")
        p[key] = value
    order = ("history", "depth", "reliability", "durability", "deadline", "lifespan",
             "liveliness", "liveliness_lease_duration", "avoid_ros_namespace_conventions")
    return yaml.safe_dump([{k: p[k] for k in order}], sort_keys=False,
                          default_flow_style=False).strip()


#: Longest ``offered_qos_profiles`` text read [characters] (one profile is about 400).
MAX_QOS_TEXT = 64 << 10


class _NoAliases(yaml.SafeLoader):
    """YAML without anchors and aliases: QoS text never needs them, and they can explode."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            raise yaml.YAMLError("uses a YAML alias")
        return super().compose_node(parent, index)


def parse_qos_profiles(text: str) -> list[dict]:
    """Parse ``offered_qos_profiles`` (YAML text or list) into a list of dicts.

    Parameters
    ----------
    text : str or list

    Returns
    -------
    list of dict

    Raises
    ------
    ValueError
        Not a list of mappings (or longer than :data:`MAX_QOS_TEXT`, or using YAML aliases).
    """
    if not text:
        return []
    if isinstance(text, str):
        if len(text) > MAX_QOS_TEXT:
            raise ValueError(f"offered_qos_profiles is {len(text)} characters long, not a QoS "
                             "list")
        try:
            data = yaml.load(text, Loader=_NoAliases)  # noqa: S506 - a safe loader
        except yaml.YAMLError as exc:
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise ValueError(f"offered_qos_profiles is not YAML ({first})") from None
    else:
        data = text
    if data is None:
        return []
    if not isinstance(data, list) or not all(isinstance(p, dict) for p in data):
        raise ValueError("offered_qos_profiles is not a list of QoS profiles")
    return [dict(p) for p in data]


def _whole(value) -> int:
    """A recorded whole number, 0 when it is none (a QoS value from a file may be anything)."""
    try:
        return int(value) if not isinstance(value, float) or value.is_integer() else 0
    except (TypeError, ValueError, OverflowError):
        return 0


def qos_from_profile(profile: dict | None):
    """rclpy ``QoSProfile`` from one recorded ``offered_qos_profiles`` entry.

    Unset or infinite durations are left to the middleware default (infinite); a value that
    is not one of the policy's (a damaged file) gives the default of that policy.

    Parameters
    ----------
    profile : dict or None
        Parsed profile (string or integer policy values); None gives reliable, volatile,
        keep_last 10.

    Returns
    -------
    rclpy.qos.QoSProfile
    """
    from rclpy.duration import Duration
    from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                           ReliabilityPolicy)

    p = dict(profile or {})

    def policy(enum, key, default):
        value = p.get(key, default)
        try:
            member = enum(value) if isinstance(value, int) else enum[str(value).upper()]
        except (KeyError, ValueError):
            member = enum[default.upper()]
        # "unknown" and "best_available" are not offerable by a publisher
        return member if member.name not in ("UNKNOWN", "BEST_AVAILABLE") \
            else enum[default.upper()]

    history = policy(HistoryPolicy, "history", "keep_last")
    depth = _whole(p.get("depth", 10))
    if history == HistoryPolicy.KEEP_LAST and not 1 <= depth < 2 ** 31:
        depth = 10
    qos = QoSProfile(history=history, depth=depth,
                     reliability=policy(ReliabilityPolicy, "reliability", "reliable"),
                     durability=policy(DurabilityPolicy, "durability", "volatile"),
                     liveliness=policy(LivelinessPolicy, "liveliness", "system_default"),
                     avoid_ros_namespace_conventions=bool(
                         p.get("avoid_ros_namespace_conventions", False)))
    for key in ("deadline", "lifespan", "liveliness_lease_duration"):
        d = p.get(key)
        if not isinstance(d, dict):
            continue
        ns = _whole(d.get("sec", 0)) * 1_000_000_000 + _whole(d.get("nsec", 0))
        if 0 < ns < _INFINITE_NS:
            setattr(qos, key, Duration(nanoseconds=ns))
    return qos
