"""What both node programs do around their node: arguments, unknown parameters, signals.

In-process and without a running graph (the end-to-end cases are in test_sim_node.py and
test_replay.py).
"""
from __future__ import annotations

import os
import signal

import pytest
# a broken ROS installation fails these tests; it never skips them
from rclpy.parameter import Parameter

from ltd_brake_ros.ros import program
from ltd_brake_ros.ros.params import PARAMETERS, StartupError
from ltd_brake_ros.ros.program import Interrupted, Signals, unknown_parameters

pytestmark = pytest.mark.ros

USAGE = "prog BAG [--ros-args ...]"


def test_arguments_are_read_the_way_rcl_reads_them():
    argv = ["prog", "bag", "--ros-args", "-p", "a:=1", "--params-file", "f.yaml", "-r",
            "__ns:=/x", "--", "more", "--ros-args", "--params-file", "g.yaml"]
    assert program._split_arguments(argv) == (["bag", "more"], ["f.yaml", "g.yaml"])
    assert program._split_arguments(["prog"]) == ([], [])


def test_a_stray_argument_or_an_unreadable_parameter_file_is_refused(tmp_path):
    params = tmp_path / "p.yaml"
    params.write_text("prog:\n  ros__parameters: {a: 1}\n")
    ok = ["prog", "bag", "--ros-args", "--params-file", str(params)]
    assert program._argument_problem(ok, ["BAG"], USAGE) is None
    # without --ros-args the parameter would silently not be set
    assert program._argument_problem(["prog", "-p", "record:=true"], [], USAGE) == \
        f"unexpected argument '-p'; usage: {USAGE}"
    assert program._argument_problem(["prog", "bag", "extra"], ["BAG"], USAGE) == \
        f"unexpected argument 'extra'; usage: {USAGE}"
    missing = ["prog", "--ros-args", "--params-file", str(tmp_path / "none.yaml")]
    assert program._argument_problem(missing, [], USAGE) == \
        f"--params-file {tmp_path / 'none.yaml'}: no such file"


def test_rcl_errors_become_one_line_without_source_locations():
    raw = ("failed to initialize rcl: Couldn't parse params file: '--params-file b.yaml'. "
           "Error: Cannot have a value before ros__parameters at line 2, at "
           "/project/src/parse.c:818, at /project/src/rcl/arguments.c:415")
    assert program._rcl_reason(RuntimeError(raw)) == (
        "Couldn't parse params file: '--params-file b.yaml'. Error: Cannot have a value "
        "before ros__parameters at line 2")


def test_a_parameter_the_node_does_not_have_is_named_with_the_closest_ones(ros_context):
    from ltd_brake_ros.ros.sim_node import SimNode

    with pytest.raises(StartupError) as err:
        SimNode(context=ros_context, namespace="/typo",
                parameter_overrides=[Parameter("recrod", value=True)])
    assert str(err.value) == ("parameter recrod: sim_node has no such parameter (did you mean "
                              "record or record_dir?)")
    # nothing close: the node's parameters are listed
    node = _bare_node(ros_context, [Parameter("zzz", value=1)])
    try:
        name, reason = unknown_parameters(node, [p.name for p in PARAMETERS])
        assert name == "zzz" and reason.startswith("bare has no such parameter (it has consist, ")
    finally:
        node.destroy_node()
    # rclpy's own parameters are known to every node
    node = _bare_node(ros_context, [Parameter("use_sim_time", value=True)])
    try:
        assert unknown_parameters(node, []) is None
    finally:
        node.destroy_node()


def _bare_node(context, overrides):
    import rclpy

    return rclpy.create_node("bare", context=context, parameter_overrides=overrides)


@pytest.fixture
def signals():
    """A :class:`Signals` installed in this process; the previous handlers come back after."""
    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield Signals("prog").install()
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)


def test_while_starting_the_first_signal_interrupts(signals):
    with pytest.raises(Interrupted) as err:
        with signals.interruptible():
            os.kill(os.getpid(), signal.SIGTERM)
    assert err.value.signum == signal.SIGTERM and str(err.value) == "SIGTERM"
    assert signals.received == signal.SIGTERM
    # once received, a further start-up step is not begun
    with pytest.raises(Interrupted):
        with signals.interruptible():
            pass


def test_a_signal_lost_in_a_c_callback_still_ends_start_up_quietly(signals, capfd):
    """numba's compiler calls back into Python from C: an exception raised there cannot
    propagate (Python prints it as "Exception ignored"); start-up must end all the same."""
    import ctypes

    steps = []

    @ctypes.CFUNCTYPE(None)
    def callback():
        os.kill(os.getpid(), signal.SIGINT)
        steps.append("after the signal, inside the callback")

    with pytest.raises(Interrupted):
        with signals.interruptible():
            callback()
            steps.append("after the callback")
    assert steps == ["after the callback"]  # the callback ended at the signal, start-up did not
    assert "Exception ignored" not in capfd.readouterr().err


_FINALIZER_FAILS = """
import gc, os, signal, sys
from ltd_brake_ros.ros.program import Interrupted, Signals

class Handle:
    def __init__(self, interrupt):
        if interrupt:
            os.kill(os.getpid(), signal.SIGTERM)
        self.pointer = 1

    def __del__(self):
        del self.pointer
        del self.pointer  # fails: a defect of the finalizer

signals = Signals("prog").install()
if sys.argv[1] == "interrupted":
    try:
        with signals.interruptible():
            Handle(True)
    except Interrupted:
        pass
else:
    Handle(False)
gc.collect()
print("end")
"""


@pytest.mark.parametrize("when", ["interrupted", "running"])
def test_a_failing_finalizer_is_quiet_only_once_a_signal_stops_the_program(when):
    """A signal that interrupts an object's construction (llvmlite's, while the kernel loads)
    leaves it without the attributes its finalizer deletes, and the stopping program collects
    it: no "Exception ignored" then. Without a signal such a failure is still reported."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _FINALIZER_FAILS, when], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == "end", out.stderr
    assert ("Exception ignored" in out.stderr) == (when == "running"), out.stderr


def test_while_running_a_signal_is_remembered_and_a_further_one_only_logged(signals, capfd):
    os.kill(os.getpid(), signal.SIGINT)
    assert signals.received == signal.SIGINT  # no KeyboardInterrupt: the loop ends by itself
    os.kill(os.getpid(), signal.SIGTERM)
    assert signals.received == signal.SIGINT
    assert "SIGTERM ignored: shutting down, finishing what is open (SIGKILL aborts)" in \
        capfd.readouterr().err


def test_the_program_is_recognised_by_its_first_argument(monkeypatch):
    monkeypatch.setattr("sys.argv", ["/usr/lib/ltd_brake_ros/other_node", "x"])
    assert program.install_if_program("sim_node") is None


def test_the_threaded_executor_waits_for_a_callback_to_start_instead_of_offering_it_again(
        ros_context):
    """While every pool thread is busy, a ready callback is handed over once per
    START_WAIT_S, not thousands of times a second (which held the interpreter lock and
    slowed every lock-step step about tenfold); it still runs once a thread is free."""
    import threading
    import time
    import warnings

    import rclpy
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup

    node = rclpy.create_node("executor_probe", context=ros_context)
    with warnings.catch_warnings():  # rclpy advises a single-threaded one for one thread
        warnings.simplefilter("ignore", UserWarning)
        executor = program.threaded_executor(1, context=ros_context)
    release, ran = threading.Event(), []
    try:
        # the pool's one thread waits in the first callback; the second one is ready meanwhile
        blocker = node.create_timer(0.001, lambda: (blocker.cancel(), release.wait(10.0)),
                                    callback_group=MutuallyExclusiveCallbackGroup())
        node.create_timer(0.001, lambda: ran.append(1),
                          callback_group=MutuallyExclusiveCallbackGroup())
        executor.add_node(node)
        offered = 0
        pool = executor._executor
        submit = pool.submit

        def counting(*args, **kwargs):  # every hand-over of a callback to the pool
            nonlocal offered
            offered += 1
            return submit(*args, **kwargs)

        pool.submit = counting

        def spin(seconds):
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                executor.spin_once(timeout_sec=0.05)

        spin(0.5)  # the first callback starts and blocks the pool
        offered = 0
        spin(2.0)
        assert not ran
        # one wait of START_WAIT_S per hand-over (rclpy's own hands it over about 40 times a
        # second with one thread, thousands with three)
        assert offered <= 2.0 / program.START_WAIT_S + 1
        release.set()
        end = time.monotonic() + 10.0
        while not ran and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        assert ran
    finally:
        release.set()
        executor.shutdown()
        node.destroy_node()
