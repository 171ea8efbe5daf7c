"""The Foxglove and PlotJuggler layouts name only what the plant publishes.

Every message path of the Foxglove layout and every curve of the PlotJuggler layout must name a
topic of the plant's topic table (``recording.plant_topics``: what ``sim_node`` publishes and a
recording holds), a field its message type has, and for the per-vehicle and per-coupler
``sensor_msgs/JointState`` topics a joint name the node gives (checked on paper scenario 6,
which the layouts are drawn for).
"""
from __future__ import annotations

import importlib
import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from ltd_brake_ros.recording.frames import (HEAD_FRAME, MARKERS_TOPIC, MARKERS_TYPE,
                                            ODOM_TOPIC, ODOM_TYPE)
from ltd_brake_ros.recording.plant_topics import STATE_TOPICS, joint_names, plant_topics

pytestmark = pytest.mark.ros

LAYOUTS = Path(__file__).resolve().parents[2] / "layouts"
#: Scenario 6: E402B + 32 Shimmns.
VEHICLES, COUPLERS = 33, 32


def _topic_types() -> dict[str, str]:
    types = {name: msg_type for name, msg_type, _ in plant_topics("/")}
    return types | {f"/{ODOM_TOPIC}": ODOM_TYPE, f"/{MARKERS_TOPIC}": MARKERS_TYPE}


def _message_class(msg_type: str):
    package, _, name = msg_type.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def _joint_names(topic: str) -> list[str]:
    """Names the plant gives the joints of a JointState topic, for scenario 6."""
    from ltd_brake_ros.inputs import get_scenario

    kind, = (k for t, k in STATE_TOPICS if f"/{t}" == topic)
    names = joint_names(kind, get_scenario(6).consist().n)
    assert len(names) == (VEHICLES if kind == "vehicle" else COUPLERS)
    return names


def _check_field(topic: str, fields: list[tuple[str, str | None]]) -> None:
    """``fields``: (field, index text or None) from the path after the topic, outermost
    first; only the last may be indexed."""
    types = _topic_types()
    assert topic in types, f"{topic} is not a plant topic"
    cls = _message_class(types[topic])
    *outer, (field, index) = fields
    for name, _ in outer:  # nested messages
        kind = cls.get_fields_and_field_types().get(name)
        assert kind and "/" in kind, f"{topic} ({types[topic]}) has no message field {name}"
        package, name = kind.split("/")
        cls = _message_class(f"{package}/msg/{name}")
    kinds = cls.get_fields_and_field_types()
    assert field in kinds, f"{topic} ({types[topic]}) has no field {field}"
    if index is None:
        assert kinds[field] == "double", (topic, field, kinds[field])
    else:
        assert kinds[field].startswith("sequence<double"), (topic, field, kinds[field])
        assert re.fullmatch(r"-?\d+|:", index), (topic, index)
        if index not in (":", "-1"):
            bound = COUPLERS if topic.startswith("/couplers") else VEHICLES
            assert 0 <= int(index) < bound, f"{topic}.{field}[{index}] is beyond scenario 6"


# --------------------------------------------------------------------------- Foxglove


FOXGLOVE_PATH = re.compile(r"(?P<topic>/[A-Za-z0-9_/]+)\.(?P<fields>[a-z_]+(?:\.[a-z_]+)*)"
                           r"(?:\[(?P<index>-?\d+|:)\])?")


def _tree_leaves(node) -> list[str]:
    if isinstance(node, str):
        return [node]
    return _tree_leaves(node["first"]) + _tree_leaves(node["second"])


def test_foxglove_layout_plots_plant_topics_and_places_every_panel():
    layout = json.loads((LAYOUTS / "foxglove_train.json").read_text())
    panels = layout["configById"]
    assert sorted(_tree_leaves(layout["layout"])) == sorted(panels)
    plotted = set()
    # the 3D panel shows the plant's markers and follows the head's frame, which they are
    # drawn in (a plant in the root namespace: no prefix)
    scene = panels.pop("3D!train")
    assert scene["followTf"] == HEAD_FRAME and scene["followMode"] == "follow-position"
    assert scene["topics"] == {f"/{MARKERS_TOPIC}": {"visible": True}}
    for panel, config in panels.items():
        assert panel.split("!")[0] == "Plot", f"{panel}: only Plot panels are checked here"
        assert config["xAxisVal"] in ("timestamp", "index"), panel
        for path in config["paths"]:
            match = FOXGLOVE_PATH.fullmatch(path["value"])
            assert match, f"{panel}: {path['value']} is not topic.field[index]"
            names = match["fields"].split(".")
            _check_field(match["topic"], [(n, None) for n in names[:-1]]
                         + [(names[-1], match["index"])])
            # stamped topics plot against simulated time, live or recorded
            assert path["timestampMethod"] == "headerStamp", (panel, path)
            plotted.add(match["topic"])
            if config["xAxisVal"] == "index":  # one value per coupler at the playback time
                assert match["index"] == ":", (panel, path)
    assert plotted == {"/vehicles/state", "/couplers/state", f"/{ODOM_TOPIC}"}
    coupler_map = [p["value"] for p in panels["Plot!couplermap"]["paths"]]
    assert coupler_map == [f"/couplers/state.effort[{i}]" for i in range(COUPLERS)]


# --------------------------------------------------------------------------- PlotJuggler


def test_plotjuggler_layout_curves_are_joints_the_plant_publishes():
    root = ET.parse(LAYOUTS / "plotjuggler_train.xml").getroot()
    types = _topic_types()
    curves = [c.get("name") for c in root.iter("curve")]
    assert len(curves) > COUPLERS
    for curve in curves:
        if curve.startswith(f"/{ODOM_TOPIC}/"):  # the message's fields, nested
            names = curve[len(ODOM_TOPIC) + 2:].split("/")
            _check_field(f"/{ODOM_TOPIC}", [(n, None) for n in names])
            continue
        topic, joint, field = curve.rsplit("/", 2)
        assert types.get(topic) == "sensor_msgs/msg/JointState", curve
        assert joint in _joint_names(topic), f"{curve}: no joint {joint} in scenario 6"
        assert field in ("position", "velocity", "effort"), curve
    # plotjuggler-ros-plugins' subscriber reads its preselection from one attribute,
    # <selected_topics value="a;b"/>, not from child elements
    selected = [e for e in root.iter("selected_topics")]
    assert len(selected) == 1 and not list(selected[0])
    subscribed = selected[0].get("value", "").split(";")
    assert subscribed and all(subscribed) and set(subscribed) <= set(types)
    assert {"/vehicles/state", "/couplers/state"} <= set(subscribed)
    plugins = {p.get("ID"): p for p in root.iter("plugin")}
    assert {"DataLoad MCAP", "ROS2 Topic Subscriber"} <= set(plugins)
    # every series against its header stamp (simulated time), recorded or live: the state
    # PlotJuggler itself saves for its MCAP loader and for the ROS 2 subscriber
    loader, = plugins["DataLoad MCAP"].iter("parameters")
    assert loader.get("use_timestamp") == "1" and loader.get("use_mcap_log_time") == "0"
    assert set(loader.get("selected_topics").split(";")) == set(subscribed)
    stamp, = plugins["ROS2 Topic Subscriber"].iter("use_header_stamp")
    assert stamp.get("value") == "true"
