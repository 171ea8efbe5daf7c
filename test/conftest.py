"""Shared test set-up: ROS 2 isolation, a test-side ROS probe and child-process hygiene.

Every session claims a DDS domain of its own (``ROS_DOMAIN_ID`` in 1..101, locked for the
session's lifetime, never one in which a process already runs) with discovery limited to this
machine, so two test runs on one host never hear each other, and neither hears a node left from
elsewhere. Child processes inherit that environment. Every process started through
:class:`ProcessGroup` runs in its own session, is killed (whole process group) when the test
ends, pass or fail, and dies with the test process if that is killed.
"""
from __future__ import annotations

import ctypes
import fcntl
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import pytest

#: Console scripts of the package (the venv's ``bin``, where ``pip install -e`` put them).
BIN_DIR = Path(sys.executable).parent


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    """A module that skips itself (``pytest.importorskip``) fails instead: see below."""
    report = (yield).get_result()
    _never_skip(report)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A skipped test fails: a missing dependency or a broken installation (rclpy that does
    not import) must not make a layer of the suite vanish from a green run."""
    report = (yield).get_result()
    _never_skip(report)


def _never_skip(report) -> None:
    if report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else report.longrepr
        report.outcome = "failed"
        report.longrepr = f"skipped ({reason}): this suite never skips; fix what is missing"


#: Domains a session may claim (0, the default, is left to interactive use; above 101 the
#: DDS ports leave the range Linux keeps free of ephemeral ports).
DOMAINS = range(1, 102)
#: The session's claim on its domain: an open, locked file, released by the kernel when the
#: process ends, however it ends.
_domain_claim = None
_private_cache = None


def _domain_in_use(domain: int) -> bool:
    """True if a running process was started with ``ROS_DOMAIN_ID=domain``."""
    needle = f"ROS_DOMAIN_ID={domain}".encode()
    for environ in Path("/proc").glob("[0-9]*/environ"):
        try:
            if needle in environ.read_bytes().split(b"\0"):
                return True
        except OSError:  # gone, or another user's
            continue
    return False


def _claim_domain() -> int:
    """Claim a DDS domain no other session on this machine holds and no process uses."""
    global _domain_claim
    folder = Path(tempfile.gettempdir()) / "ltd_brake_ros-test-domains"
    folder.mkdir(exist_ok=True)
    candidates = list(DOMAINS)
    random.SystemRandom().shuffle(candidates)
    for domain in candidates:
        claim = open(folder / f"{domain}.lock", "a")  # noqa: SIM115 - held for the session
        try:
            fcntl.flock(claim, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:  # another session's
            claim.close()
            continue
        if _domain_in_use(domain):  # e.g. a node left running by a killed session
            claim.close()
            continue
        _domain_claim = claim
        return domain
    raise pytest.UsageError(f"no free ROS domain in {DOMAINS.start}..{DOMAINS.stop - 1}")


def pytest_unconfigure(config):
    """Release the session's domain claim; remove its private folder."""
    if _domain_claim is not None:
        _domain_claim.close()
    if _private_cache is not None:
        shutil.rmtree(_private_cache, ignore_errors=True)


def pytest_configure(config):
    """Isolate the session's DDS traffic before anything initialises ROS."""
    os.environ["ROS_DOMAIN_ID"] = str(_claim_domain())
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    # a first run compiles its kernels in place: a background compile would outlive its test
    # (the tests of the background compile ask for it and wait for it)
    os.environ["LTD_BRAKE_FIRST_RUN"] = "wait"
    # the user's private folder (compile lock, log, compile times) is the session's own
    global _private_cache
    _private_cache = tempfile.mkdtemp(prefix="ltd_brake_ros-test-cache-")
    os.environ["XDG_CACHE_HOME"] = _private_cache
    for name in ("ROS_STATIC_PEERS", "ROS_LOCALHOST_ONLY", "ROS_DISCOVERY_SERVER"):
        os.environ.pop(name, None)


def executable(name: str) -> str:
    """Path of an installed console script (``sim_node``, ``ltd-brake``, ...)."""
    path = BIN_DIR / name
    if not path.exists():
        pytest.fail(f"{name} is not installed in {BIN_DIR} (run ./dev.sh setup)")
    return str(path)


# --------------------------------------------------------------------------- child processes


def _die_with_parent() -> None:
    """In a child before exec: SIGKILL it when the test process dies (Linux ``prctl``).

    A test process that is killed (a CI time-out) cannot kill its children; without this a
    node started in its own session would run on, in a domain a later session may claim.
    The setting survives exec.
    """
    PR_SET_PDEATHSIG = 1
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)


class NodeProcess:
    """A child process in its own session, output captured to a file.

    Parameters
    ----------
    argv : list of str
        Command line.
    log_path : pathlib.Path
        File receiving stdout and stderr.
    env : dict, optional
        Environment (default: this process's).
    """

    def __init__(self, argv: list[str], log_path: Path, env: dict | None = None):
        self.argv, self.log_path = argv, log_path
        self._log = open(log_path, "wb")
        # own session: the process group can be killed as a whole; the ROS wheels re-exec the
        # interpreter with execve, so the pid stays the node's pid
        self.popen = subprocess.Popen(argv, stdout=self._log, stderr=subprocess.STDOUT,
                                      stdin=subprocess.DEVNULL, env=env, start_new_session=True,
                                      preexec_fn=_die_with_parent)

    @property
    def pid(self) -> int:
        """Process id."""
        return self.popen.pid

    def output(self) -> str:
        """Everything the process wrote so far."""
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors="replace")

    def wait(self, timeout_s: float = 60.0) -> int:
        """Wait for exit; kill and fail the test if it takes longer than ``timeout_s``."""
        try:
            return self.popen.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            self.kill()
            pytest.fail(f"{self.argv[0]} did not exit within {timeout_s:g} s:\n{self.output()}")

    def stop(self, sig: int = signal.SIGINT, timeout_s: float = 20.0) -> int:
        """Send ``sig`` to the process and return its exit status."""
        if self.popen.poll() is None:
            os.kill(self.pid, sig)
        return self.wait(timeout_s)

    def kill(self) -> None:
        """SIGKILL the whole process group (idempotent)."""
        if self.popen.poll() is None:
            try:
                os.killpg(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self.popen.wait(timeout=10)
        self._log.close()


class ProcessGroup:
    """Starts child processes and kills every one of them on :meth:`close`."""

    def __init__(self, log_dir: Path):
        self.log_dir = log_dir
        self.processes: list[NodeProcess] = []

    def start(self, *argv: str, env: dict | None = None, name: str | None = None) -> NodeProcess:
        """Start ``argv`` with output to ``<log_dir>/<name>.log``."""
        name = name or f"{Path(argv[0]).name}-{len(self.processes)}"
        proc = NodeProcess(list(argv), self.log_dir / f"{name}.log", env)
        self.processes.append(proc)
        return proc

    def close(self) -> None:
        """Kill every process still running."""
        for proc in self.processes:
            proc.kill()


@pytest.fixture
def processes(tmp_path):
    """A :class:`ProcessGroup` whose processes are killed when the test ends."""
    group = ProcessGroup(tmp_path)
    try:
        yield group
    finally:
        group.close()


# --------------------------------------------------------------------------- ROS probe


@pytest.fixture(scope="session")
def ros_context():
    """An initialised rclpy context for the test process (no signal handlers installed)."""
    import rclpy  # a broken ROS installation fails the ROS tests; it never skips them
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    yield context
    rclpy.try_shutdown(context=context)


class RosProbe:
    """A test-side node: collects messages, publishes, calls services and sets parameters.

    Parameters
    ----------
    context : rclpy.context.Context
    name : str, optional
        Base name of the node.
    """

    _count = 0

    def __init__(self, context, name: str = "probe"):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        RosProbe._count += 1
        self.node = rclpy.create_node(f"{name}_{os.getpid()}_{RosProbe._count}",
                                      context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        #: topic -> list of received messages (or bytes for raw subscriptions), in order
        self.received: dict[str, list] = defaultdict(list)
        self._clients: dict[str, object] = {}
        self._publishers: dict[str, object] = {}
        self._subscriptions: dict[str, object] = {}

    def subscribe(self, topic: str, msg_type, raw: bool = False, depth: int = 1000):
        """Collect every message on ``topic`` into ``received[topic]`` (reliable reader)."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        qos = QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE)
        sub = self.node.create_subscription(msg_type, topic, self.received[topic].append, qos,
                                            raw=raw)
        self._subscriptions[topic] = sub
        return sub

    def wait_matched(self, topics, timeout_s: float = 60.0) -> None:
        """Wait until the probe's reader of each of ``topics`` has matched a writer.

        Discovered is not matched: messages published before the match are not delivered.
        """
        for topic in topics:
            sub = self._subscriptions[topic]
            self.spin_until(lambda: sub.get_publisher_count() > 0, timeout_s,
                            f"a publisher matched on {topic}")

    def spin_for(self, seconds: float) -> None:
        """Process callbacks for ``seconds`` of wall time."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.02)

    def spin_until(self, predicate, timeout_s: float, what: str) -> None:
        """Process callbacks until ``predicate()`` is true; fail naming ``what`` on timeout."""
        end = time.monotonic() + timeout_s
        while not predicate():
            if time.monotonic() > end:
                pytest.fail(f"timed out after {timeout_s:g} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.02)

    def publish(self, topic: str, msg, timeout_s: float = 60.0) -> None:
        """Publish ``msg`` once a subscriber has matched (reliable, depth 10)."""
        if topic not in self._publishers:
            self._publishers[topic] = self.node.create_publisher(type(msg), topic, 10)
        pub = self._publishers[topic]
        self.spin_until(lambda: pub.get_subscription_count() > 0, timeout_s,
                        f"a subscriber on {topic}")
        pub.publish(msg)

    def client(self, srv_type, name: str):
        """The probe's client of service ``name`` (created once).

        Creating clients before the server starts lets the server discover them together
        with the probe's other endpoints: a response sent before the server has matched the
        client's reader is lost.
        """
        if name not in self._clients:
            self._clients[name] = self.node.create_client(srv_type, name)
        return self._clients[name]

    def prepare(self, node: str, *services: str) -> None:
        """Create the clients of ``node``'s services (``pause``, ``reset``, ``step``,
        ``restart``, ``set_parameters``, ``get_parameters``) before the node starts.

        The node then discovers them with the probe's other endpoints; once it reports to the
        probe (diagnostics arrive) it can answer them. A client created after the node started
        may lose its first reply.
        """
        from rcl_interfaces.srv import GetParameters, SetParameters
        from std_srvs.srv import SetBool, Trigger

        types = {"pause": SetBool, "reset": Trigger, "step": Trigger, "restart": Trigger,
                 "set_parameters": SetParameters, "get_parameters": GetParameters}
        for service in services:
            self.client(types[service], f"{node}/{service}")

    #: Seconds without a response after which a request that may be repeated is sent again.
    RESEND_S = 5.0

    def call(self, srv_type, name: str, request, timeout_s: float = 30.0):
        """Call a service and return its response (see :meth:`prepare`).

        A server drops its response when it has not yet discovered the client's response
        reader (Fast DDS waits 100 ms for it): after a lost discovery packet, that takes a
        retransmission. A request that may be repeated (pause, get or set parameters) is then
        sent again every :data:`RESEND_S`; a step or a reset, which must not happen twice,
        is sent once.
        """
        from rcl_interfaces.srv import GetParameters, SetParameters
        from std_srvs.srv import SetBool

        client = self.client(srv_type, name)
        self.spin_until(client.service_is_ready, timeout_s, f"service {name}")
        futures = [client.call_async(request)]
        resend = srv_type in (SetBool, GetParameters, SetParameters)
        now = time.monotonic()
        end, next_send = now + timeout_s, now + self.RESEND_S
        while not any(f.done() for f in futures):
            now = time.monotonic()
            if now > end:
                sent = f" ({len(futures)} requests sent)" if len(futures) > 1 else ""
                pytest.fail(f"timed out after {timeout_s:g} s waiting for the response of "
                            f"{name}{sent}")
            if resend and now >= next_send:
                futures.append(client.call_async(request))
                next_send = now + self.RESEND_S
            self.executor.spin_once(timeout_sec=0.02)
        for f in futures:
            if not f.done():
                client.remove_pending_request(f)
        return next(f for f in futures if f.done()).result()

    def set_parameters(self, node: str, **values):
        """Set parameters of ``node`` one by one; returns the list of SetParametersResult."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        request = SetParameters.Request(
            parameters=[Parameter(k, value=v).to_parameter_msg() for k, v in values.items()])
        return self.call(SetParameters, f"{node}/set_parameters", request).results

    def get_parameters(self, node: str, *names: str) -> list:
        """Current values of parameters of ``node``."""
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import parameter_value_to_python

        response = self.call(GetParameters, f"{node}/get_parameters",
                             GetParameters.Request(names=list(names)))
        return [parameter_value_to_python(v) for v in response.values]

    def close(self) -> None:
        """Destroy the node and its executor."""
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def probe(ros_context):
    """A :class:`RosProbe`, destroyed when the test ends."""
    p = RosProbe(ros_context)
    try:
        yield p
    finally:
        p.close()
