"""The statuses ``hil vessel`` publishes on ``/diagnostics`` about once a second.

Five statuses, named after the stack's node (``hil_stack: pose feed`` ...):

- **pose feed**, **IMU feed** (hardware id: the topic): messages received, accepted and
  refused (by reason, with the fix), rate over the last period (Hz) and age of the
  newest sample accepted (s). ERROR when no pose was ever accepted or the newest is
  older than ``[loop] pose_timeout_s`` (the loop holds with zero thrust); WARN when
  messages were refused during the last period; the IMU's faults are WARN (the EKF
  flies on the pose alone).
- **premises**: the pose and IMU feeds of the last period judged as ``hil vessel
  --check`` judges them (:mod:`hil.runs.feed_check`: rate, jitter, time source,
  latency, frame id, NaN share), and the EKF's consistency. WARN when a feed premise
  fails (the guarantee is not known to hold under it), ERROR once the estimate broke
  its noise model (the run is aborted).
- **controller**: version in force, synthesis state, mode, the last decision. ERROR
  when the run aborted or there is no controller and none is being synthesized; WARN
  while synthesizing without one, after a failed synthesis, or when the last decision
  was not winning.
- **loop**: nominal rate, ticks and period jitter (p99) over the last period, overruns
  and late decision intervals. STALE before the loop runs (waiting for the first pose);
  ERROR when a decision interval came late (the one-step guarantee does not cover it);
  WARN when ticks overran.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

from hil.adapters.feed_health import FeedHealth
from hil.adapters.feed_tape import Heard
from hil.adapters.ros_telemetry import Diagnostic, DiagnosticLevel
from hil.core.clock import NS_PER_S
from hil.core.records import Decision
from hil.runs.feed_check import judge_imu_feed, judge_pose_feed, series_of
from hil.runs.summary import period_jitter_p99_ms
from hil.runtime.loop import Runtime
from hil.runtime.mode import Mode

__all__ = ["FeedView", "VesselDiagnostics", "feed_status"]

OK, WARN, ERROR, STALE = (DiagnosticLevel.OK, DiagnosticLevel.WARN, DiagnosticLevel.ERROR,
                          DiagnosticLevel.STALE)


@dataclass(frozen=True)
class FeedView:
    """Where the diagnostics read the sensor feeds.

    Attributes:
        pose: The pose feed's counters now.
        imu: The IMU feed's counters now.
        heard: The pose and IMU messages that arrived since a node-clock time (ns);
            None where the pose does not come over ROS (QTM): no premise lines then.
        pose_frame_id: The expected pose frame (``[ros] pose_frame_id``).
        sim_time: Whether hil follows ``/clock``.
    """

    pose: Callable[[], FeedHealth]
    imu: Callable[[], FeedHealth]
    heard: Callable[[int], tuple[Heard, Heard]] | None
    pose_frame_id: str
    sim_time: bool


def feed_status(name: str, health: FeedHealth, now_ns: int, period_s: float,
                rejected_before: int, timeout_s: float, critical: bool) -> Diagnostic:
    """Return one feed's status.

    Args:
        name: The status's name.
        health: The feed's counters now.
        now_ns: The node clock (ns).
        period_s: The period since the last status (s), for the rate.
        rejected_before: Messages the feed had refused at the last status.
        timeout_s: Age of the newest accepted sample beyond which the feed is lost (s).
        critical: ERROR (the pose) rather than WARN (the IMU) when lost.
    """
    lost = ERROR if critical else WARN
    age_s = None if health.last_ns is None else (now_ns - health.last_ns) / NS_PER_S
    values = [("received", str(health.received)), ("accepted", str(health.accepted)),
              ("rejected", str(health.rejected)),
              ("age of the newest accepted (s)", "none yet" if age_s is None else f"{age_s:.3f}")]
    values += [(f"rejected: {r.reason.value}", r.text()) for r in health.rejections]
    refused_now = health.rejected - rejected_before
    if age_s is None:
        level, message = lost, f"none accepted: {health.describe()}"
    elif age_s > timeout_s:
        level, message = lost, f"no {health.noun} for {age_s:.1f} s (timeout {timeout_s:g} s)"
    elif refused_now > 0 or (health.rejections and health.accepted == 0):
        level, message = WARN, (f"{refused_now} refused in the last {period_s:.1f} s: "
                                f"{health.describe()}")
    else:
        level, message = OK, f"newest {1000 * age_s:.0f} ms old, none refused lately"
    return Diagnostic(name, level, message, health.topic, tuple(values))


class VesselDiagnostics:
    """Builds the statuses of a running ``hil vessel``, one call per period.

    Called on the telemetry thread: it only reads the runtime's counters.

    Args:
        runtime: The running stack.
        feeds: The sensor feeds.
        last_decision: The newest decision taken, None before the first.
        node_name: Prefix of every status's name (the stack's node).
    """

    def __init__(self, runtime: Runtime, feeds: FeedView,
                 last_decision: Callable[[], Decision | None], node_name: str) -> None:
        self._runtime = runtime
        self._feeds = feeds
        self._last_decision = last_decision
        self._prefix = f"{node_name}: "
        self._last_ns = runtime.world.clock.now_ns()
        self._rejected = (0, 0)
        self._counts = (0, 0, 0)  # overruns, late intervals, failed syntheses at the last call

    def __call__(self) -> list[Diagnostic]:
        """Return the statuses now: pose feed, IMU feed, premises, controller, loop."""
        now_ns = self._runtime.world.clock.now_ns()
        since_ns, self._last_ns = self._last_ns, now_ns
        period_s = max(1e-9, (now_ns - since_ns) / NS_PER_S)
        timeout_s = self._runtime.config.pose_timeout_s
        pose, imu = self._feeds.pose(), self._feeds.imu()
        taken = self._runtime.feed.last_pose_ns  # the newest pose the loop took (any source)
        if taken is not None and (pose.last_ns is None or taken > pose.last_ns):
            pose = replace(pose, last_ns=taken)
        statuses = [
            feed_status(self._prefix + "pose feed", pose, now_ns, period_s, self._rejected[0],
                        timeout_s, critical=True),
            feed_status(self._prefix + "IMU feed", imu, now_ns, period_s, self._rejected[1],
                        timeout_s, critical=False),
            self._premises(since_ns),
            self._controller(),
            self._loop(since_ns, period_s),
        ]
        self._rejected = (pose.rejected, imu.rejected)
        stats = self._runtime.stats
        self._counts = (stats.overruns, stats.late_intervals, stats.failed_syntheses)
        return statuses

    def _premises(self, since_ns: int) -> Diagnostic:
        feeds, stats = self._feeds, self._runtime.stats
        values: list[tuple[str, str]] = []
        failed: list[str] = []
        if feeds.heard is not None:
            pose, imu = feeds.heard(since_ns)
            for line in (*judge_pose_feed(series_of(pose), feeds.pose_frame_id, feeds.sim_time),
                         *judge_imu_feed(series_of(imu), feeds.sim_time)):
                values.append((f"{line.topic} {line.what}",
                               f"{'held' if line.ok else 'FAILED'}: {line.value} "
                               f"(premise: {line.premise})"))
                if not line.ok:
                    failed.append(line.text())
        broke_ns = stats.estimate_inconsistent_ns
        values.append(("estimate consistent (EKF innovations)", "yes" if broke_ns is None else
                       f"no, since the pose stamped {broke_ns / NS_PER_S:.3f} s"))
        if broke_ns is not None:
            level, message = ERROR, "the estimate broke its noise model: the run is aborted"
        elif failed:
            level, message = WARN, f"{len(failed)} premise(s) failed: {failed[0]}"
        else:
            level, message = OK, "every premise held over the last period"
        return Diagnostic(self._prefix + "premises", level, message, "guarantee", tuple(values))

    def _controller(self) -> Diagnostic:
        runtime, stats = self._runtime, self._runtime.stats
        solving = runtime.resynthesizer.busy
        decision = self._last_decision()
        values = [("controller version", str(runtime.controller_version)),
                  ("synthesis", "solving" if solving else "idle"),
                  ("mode", runtime.mode.value), ("decisions", str(stats.decisions)),
                  ("re-syntheses", str(stats.resyntheses)),
                  ("failed syntheses", str(stats.failed_syntheses))]
        if stats.synthesis_seconds:
            values.append(("last synthesis (s)", f"{stats.synthesis_seconds[-1]:.3f}"))
        if decision is not None:
            values += [("last decision cell", str(decision.cell)),
                       ("last decision value", f"{decision.value:g}"),
                       ("last decision winning", str(decision.winning).lower()),
                       ("last decision safe inputs", str(len(decision.safe_inputs)))]
        if stats.aborted:
            level, message = ERROR, f"aborted: {stats.end_reason}"
        elif runtime.controller is None:
            level, message = ((WARN, "synthesizing the first controller") if solving
                              else (ERROR, "no controller"))
        elif stats.failed_syntheses > self._counts[2]:
            level, message = WARN, f"a synthesis failed; v{runtime.controller_version} stays"
        elif decision is not None and not decision.winning:
            level, message = WARN, (f"v{runtime.controller_version}: the last decision was not "
                                    "winning (staying safe, or stopped)")
        else:
            level, message = OK, (f"v{runtime.controller_version} in force, "
                                  f"{runtime.mode.value}" + (", solving" if solving else ""))
        return Diagnostic(self._prefix + "controller", level, message, "symbolic controller",
                          tuple(values))

    def _loop(self, since_ns: int, period_s: float) -> Diagnostic:
        runtime, stats = self._runtime, self._runtime.stats
        nominal_s = 1.0 / runtime.config.loop_hz
        ticks = [t for t in stats.tick_wall_ns[-int(4 * period_s / nominal_s) - 2:]
                 if t >= since_ns]
        jitter_ms = period_jitter_p99_ms(ticks, nominal_s)
        values = (("nominal rate (Hz)", f"{runtime.config.loop_hz:g}"),
                  ("ticks in the last period", str(len(ticks))),
                  ("period jitter p99 (ms)", f"{jitter_ms:.2f}"),
                  ("overruns", str(stats.overruns)),
                  ("late decision intervals", str(stats.late_intervals)))
        if not stats.tick_wall_ns:
            level, message = STALE, "not running yet (waiting for the first pose)"
        elif runtime.mode in (Mode.STOPPED, Mode.DOCKED):
            level, message = OK, f"ended: {runtime.mode.value}"
        elif stats.late_intervals > self._counts[1]:
            level, message = ERROR, (f"a decision came {stats.worst_late_s:.2f} s late "
                                     "(worst): the loop stalled")
        elif stats.overruns > self._counts[0]:
            level, message = WARN, (f"{stats.overruns - self._counts[0]} tick(s) more than a "
                                    "period late")
        else:
            level, message = OK, f"{len(ticks)} ticks, jitter p99 {jitter_ms:.1f} ms"
        return Diagnostic(self._prefix + "loop", level, message, "control loop", values)
