"""The stack on the vessel: the ROS 2 backend in wall time (or ROS sim time), recorded.

Its config, :class:`~hil.runs.vessel_config.VesselConfig`, is read by a module of its
own (``hil vessel --print-config`` needs none of the stack); it is re-exported here.

`hil vessel --config FILE` calls :func:`run_on_ros`. SIGINT and SIGTERM stop the
loop at its next tick: the thrusters get a zero command and the log is closed,
so a run interrupted on the tank still leaves a complete bag.
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hil.adapters.feed_health import FeedHealth, Rejection, RejectReason
from hil.adapters.feed_tape import Heard
from hil.adapters.interfaces import ObstacleSource, PoseSource
from hil.adapters.obstacles import StaticObstacleSource
from hil.adapters.qtm import QtmPoseSource
from hil.adapters.ros import RosBackendError, RosWorld
from hil.bag.lab_frame import DEFAULT_LAB_FRAME, LabFrame
from hil.bag.recorder import Recorder
from hil.bag.run_info import RunInfo
from hil.core.config import ConfigError
from hil.core.pose_feeds import pose_feed
from hil.core.records import EventLevel
from hil.runs.feed_premise import measure_rate, rate_refusal
from hil.runs.feed_watch import FeedWatch
from hil.runs.live_diagnostics import FeedView
from hil.runs.live_telemetry import TelemetryLog
from hil.runs.sim_run import LiveView
from hil.runs.stack_assembly import build_runtime, scenario_hash, synthesizer_for
from hil.runs.summary import RunSummary, summarize_run
from hil.runs.vessel_config import VesselConfig
from hil.runtime.assembly import layout_from_scenario, warm_up_kernels
from hil.runtime.events import EventCode
from hil.runtime.loop import Runtime, World
from hil.runtime.mode import Mode
from hil.runtime.protocols import RunLog
from hil.runtime.resynthesis import ResynthesisMode
from hil.runtime.signals import stop_on_signals
from hil.scenarios import load_scenario

Progress = Callable[[str], None]
"""Receives one line of what the run is doing (the command prints it)."""

# Seconds between status lines while the loop runs, and between reminders while waiting.
STATUS_PERIOD_S = 5.0
# Seconds of the pose feed measured after its first pose, against the premise's rate.
RATE_WINDOW_S = 1.0


def _quiet(_line: str) -> None:
    pass


def status_line(runtime: Runtime, feeds: FeedWatch | None = None) -> str:
    """Return one line on the running loop: time, mode, estimate, decisions, controller.

    With `feeds`, the ROS backend's refusals by reason and their fixes follow.
    """
    stats = runtime.stats
    t_s = (runtime.world.clock.now_ns() - stats.start_ns) / 1e9
    where = "no estimate yet"
    if stats.eta_hat:
        x, y, psi = (float(v) for v in np.asarray(stats.eta_hat[-1]).reshape(3))
        where = f"at ({x:+.2f} m, {y:+.2f} m, {np.degrees(psi):+.0f} deg)"
    return (f"t={t_s:6.1f} s  {runtime.mode.value:<9} {where}  decisions {stats.decisions}, "
            f"controller v{runtime.controller_version}, pose losses {stats.pose_losses}"
            f"{'' if feeds is None else feeds.status()}")


@contextmanager
def _status_every(period_s: float, runtime: Runtime, feeds: FeedWatch,
                  progress: Progress) -> Iterator[None]:
    """Report :func:`status_line` every `period_s` of wall time while inside the block.

    The feeds' refusals are logged as events each time; a new reason is said at once.
    """
    done = threading.Event()

    def report() -> None:
        while not done.wait(period_s):
            if runtime.mode not in (Mode.DOCKED, Mode.STOPPED):
                feeds.poll()
                progress(status_line(runtime, feeds))

    thread = threading.Thread(target=report, name="hil-status", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join(timeout=1.0)

@dataclass(frozen=True)
class _PoseFeed:
    """Where the run's poses come from, for the wait for the first one."""

    where: str
    wait_first: Callable[[float], bool]
    waiting: Callable[[], str]
    count: Callable[[], int]
    """Poses accepted so far (the rate is measured on it)."""


def _ros_pose(ros: RosWorld, topic: str, feeds: FeedWatch) -> _PoseFeed:
    return _PoseFeed(f"on {topic} (ROS domain {ros.domain_id})", ros.pose_source.wait_first,
                     lambda: feeds.waiting(topic), lambda: ros.pose_health().accepted)


def _qtm_pose(source: QtmPoseSource) -> _PoseFeed:
    cfg = source.config

    def waiting() -> str:
        c = source.counters
        return (f"{c.connects} connection(s), {c.connect_failures} failed, {c.frames} frames, "
                f"{c.lost} with body {cfg.body!r} lost: is QTM streaming, with that body?")

    return _PoseFeed(f"from QTM at {cfg.host}:{cfg.port}, body {cfg.body!r}",
                     source.wait_first, waiting, lambda: source.counters.poses)


class _SignalStop:
    """Where SIGINT and SIGTERM go from the first synthesis to the loop's end: a clean stop.

    Each asks the runtime to stop at its next tick (before the loop starts: at its first),
    the reason naming the phase it came in (:attr:`phase`), so a signal while synthesizing,
    waiting for the first pose or measuring its rate closes the log like one mid-run,
    instead of killing the process with the bag open.
    """

    def __init__(self, runtime: Runtime) -> None:
        self._runtime = runtime
        self.phase = " while synthesizing"
        """Said after the signal's name in the stop's reason ("" once the loop runs)."""
        self.requested = False
        """A signal came."""

    def __call__(self, reason: str) -> None:
        self.requested = True
        self._runtime.request_stop(reason + self.phase)


def _wait_for_pose(pose: _PoseFeed, feeds: FeedWatch, progress: Progress,
                   stop: _SignalStop) -> None:
    """Block until the first pose arrives or a signal came.

    Each new reason the feeds are refused for is said at once (with its fix); every
    :data:`STATUS_PERIOD_S` a reminder says what the pose feed delivered.
    """
    if stop.requested:
        return
    progress(f"waiting for pose {pose.where}...")
    waited_s = 0.0
    while not stop.requested and not pose.wait_first(0.1):
        feeds.poll()
        waited_s += 0.1
        if waited_s >= STATUS_PERIOD_S:
            waited_s = 0.0
            progress(f"still waiting for pose {pose.where}: {pose.waiting()}")


def _telemetry(closing: ExitStack, ros: RosWorld, log: RunLog) -> RunLog:
    """Return `log` teed to the live topics (``[ros] live_telemetry``), closed by `closing`."""
    if not ros.config.live_telemetry:
        return log
    assert ros.clock is not None
    clock = ros.clock
    try:
        telemetry = TelemetryLog(log, ros.node, clock.now_ns)
    except ImportError as err:
        raise RosBackendError(
            f"the live telemetry needs std_msgs, rcl_interfaces and diagnostic_msgs ({err}): "
            "install the 'ros' extra, or set [ros] live_telemetry = false") from err
    closing.callback(telemetry.close)
    return telemetry


def _qtm_health(source: QtmPoseSource) -> FeedHealth:
    """Return the QTM feed's counters as a feed's health (the runtime knows the newest pose)."""
    c, cfg = source.counters, source.config
    lost = (Rejection(RejectReason.NOT_FINITE, c.lost, f"frames with body {cfg.body!r} lost",
                      "check the cameras see the vessel's rigid body"),) if c.lost else ()
    return FeedHealth(f"qtm://{cfg.host}:{cfg.port}/{cfg.body}", "poses", c.frames, c.poses, lost)


def _pose_feed(closing: ExitStack, config: VesselConfig, ros: RosWorld, log: RunLog,
               feeds: FeedWatch, recorder: Recorder) -> tuple[PoseSource, _PoseFeed, FeedView]:
    """Return where the run's poses come from: the ROS topic, or QTM with a ``[qtm]`` table."""
    pose_health = ros.pose_health
    heard: Callable[[int], tuple[Heard, Heard]] | None = ros.heard
    source: PoseSource = ros.pose_source
    pose = _ros_pose(ros, config.ros.topics.pose, feeds)
    if config.qtm is not None:
        assert ros.clock is not None
        # On wall time the run clock is the system clock, which NTP may step: QTM's offset
        # follows a step at once (watched against the monotonic clock).
        qtm = closing.enter_context(QtmPoseSource(
            config.qtm, ros.clock, on_event=lambda e: log.event(e.t_ns, e.level, e.code, e.text),
            on_sample=recorder.record,
            steady=None if config.ros.use_sim_time else time.monotonic_ns,
        ))  # fmt: skip
        source, pose, heard = qtm, _qtm_pose(qtm), None
        pose_health = functools.partial(_qtm_health, qtm)
    return source, pose, FeedView(pose_health, ros.imu_health, heard, config.ros.pose_frame_id,
                                  config.ros.use_sim_time)


def _slower_than_premise(pose: _PoseFeed, config: VesselConfig, log: RunLog,
                         now_ns: Callable[[], int]) -> str:
    """Measure the pose feed's rate over :data:`RATE_WINDOW_S`; return why it is refused, or "".

    A refusal is logged (``pose_feed_premise``, ERROR) before the run stops; a window in
    which the run's clock stood still (a lockstep simulator waits for the first command)
    is logged as a warning and not judged.
    """
    feed = pose_feed(config.pose_feed)
    window = measure_rate(pose.count, RATE_WINDOW_S, now_ns)
    if not window.measured:
        log.event(max(0, now_ns()), EventLevel.WARN, EventCode.POSE_FEED_PREMISE.value,
                  f"the pose feed's rate was not measured before the run: the run's clock "
                  f"stood still for {RATE_WINDOW_S:g} s (a simulator in lockstep?)")
        return ""
    refusal = rate_refusal(window.rate_hz, feed, f"the pose feed {pose.where}",
                           window.fastest_hz)
    if refusal:
        log.event(max(0, now_ns()), EventLevel.ERROR, EventCode.POSE_FEED_PREMISE.value, refusal)
    return refusal


def run_on_ros(config: VesselConfig, out_dir: Path | None = None,
               progress: Progress = _quiet, live: LiveView | None = None) -> RunSummary:
    """Run the stack against the vessel over ROS 2 until docked, stopped or timed out.

    It synthesizes the first controller, waits for the first pose, then runs the loop,
    telling `progress` each step and a status line every :data:`STATUS_PERIOD_S`.

    Args:
        config: The vessel configuration.
        out_dir: The run's bag directory (default: a new one under `runs_dir`).
        progress: Receives one line per step (default: nothing).
        live: Wraps the run's log for a live view (``hil vessel --rerun``); None: none.

    Returns:
        The run's summary, judged on the state estimates (there is no ground truth).
    """
    wall_start = time.perf_counter()
    scenario = load_scenario(config.scenario).for_pose_feed(config.pose_feed)
    progress(f"building the abstraction for the {scenario.name!r} scenario...")
    synthesizer = synthesizer_for(scenario, threads=config.loop.synthesis_threads,
                                  prepare_outputs=True)
    if out_dir is None:
        out_dir = Path(config.runs_dir) / f"{scenario.name}-vessel-{time.strftime('%Y%m%d-%H%M%S')}"
    layout = layout_from_scenario(scenario)
    with RosWorld(config.ros, obstacles=layout, min_move_m=scenario.tracking.position_tolerance_m,
                  stale_after_s=max(1.0, config.loop.pose_timeout_s)) as ros, Recorder(
            out_dir, RunInfo.current(config.scenario, scenario_hash(scenario), None,
                                     backend="ros"),
            lab=LabFrame(config.ros.transform,
                         config.ros.pose_frame_id or DEFAULT_LAB_FRAME.frame_id),
    ) as recorder, ExitStack() as closing:
        assert ros.clock is not None
        assert ros.thruster_sink is not None
        log = _telemetry(closing, ros, recorder if live is None else live(scenario, recorder))
        feeds = FeedWatch(ros, log, progress)
        obstacles: ObstacleSource = ros.obstacle_source or StaticObstacleSource(layout)
        pose_source, pose, feed_view = _pose_feed(closing, config, ros, log, feeds, recorder)
        world = World(ros.clock, pose_source, ros.imu_source, obstacles, ros.thruster_sink)
        runtime = build_runtime(scenario, world, log, config.loop, synthesizer,
                                ResynthesisMode.THREAD)
        if isinstance(log, TelemetryLog):
            log.watch(runtime, feed_view, config.ros.node_name)
        # Compile and synthesize before the loop starts, so its first ticks keep time.
        progress("synthesizing the controller...")
        stop = _SignalStop(runtime)
        try:
            with stop_on_signals(stop):
                warm_up_kernels(config.loop.loop_hz)
                runtime.resynthesizer.submit(obstacles.latest(), runtime.report_ages.next_s())
                runtime.resynthesizer.wait_idle()
                stop.phase = " while waiting for pose"
                _wait_for_pose(pose, feeds, progress, stop)
                if not stop.requested and (
                    refusal := _slower_than_premise(pose, config, log, ros.clock.now_ns)
                ):
                    raise ConfigError(refusal)
                stop.phase = ""
                if not stop.requested:
                    progress(f"running: recording to {out_dir}")
                with _status_every(STATUS_PERIOD_S, runtime, feeds, progress):
                    stats = runtime.run()
        finally:
            runtime.resynthesizer.close()
        refused = feeds.summary()
    progress(f"stopped: {stats.end_reason}")
    eta = np.asarray(stats.eta_hat).reshape(-1, 3)
    return summarize_run(scenario=scenario, scenario_name=config.scenario, seed=None,
                         backend="ros", stats=stats, trajectory=eta,
                         velocity=np.asarray(stats.nu_hat).reshape(-1, 3),
                         wall_s=time.perf_counter() - wall_start, log=str(out_dir),
                         nominal_s=1.0 / config.loop.loop_hz, feed_rejections=refused)
