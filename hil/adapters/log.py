"""The recorded backend: a hil bag served through the adapters against a simulated clock.

The run is read with :func:`hil.bag.run_data.load_run` (the one loader: bad
messages left out, duplicates dropped, stamps put in order, each reported).
:class:`LogWorld` then serves the samples to :class:`hil.runtime.loop.Runtime`
unchanged: a poll at time t returns every sample whose delivery time (stamp plus
the sensor's delivery delay) lies before t, in stamp order, as the simulated
world delivers them; the thruster sink captures what the stack sends, and fails
where the recording says the link failed, so the loop takes the same fault path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hil.adapters.interfaces import ThrusterSinkError
from hil.bag.errors import BagError
from hil.bag.run_data import RunData, Series
from hil.core.arrays import FloatArray, IntArray
from hil.core.clock import SimClock
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, ThrusterCommand
from hil.core.timeline import in_force

THRUSTER_FAILURE_CODE = "thruster_failure"
"""Event code the runtime logs when a thruster command cannot be delivered."""


class LogDataError(BagError):
    """A recorded run that cannot be served: a stream the stack needs is missing."""


def thruster_failures_ns(run: RunData) -> frozenset[int]:
    """Return the times (ns) at which a thruster command could not be delivered."""
    return frozenset(e.t_ns for e in run.events if e.code == THRUSTER_FAILURE_CODE)


@dataclass(frozen=True, slots=True)
class LogConfig:
    """How recorded samples are delivered.

    Attributes:
        pose_delay_ns: Time from a pose's stamp to its delivery (ns); the
            simulated motion-capture latency (10 ms) by default. The recorder
            stores stamps, not arrival times, so the delay is configuration.
        imu_delay_ns: Same for the IMU (ns).
    """

    pose_delay_ns: int = 10_000_000
    imu_delay_ns: int = 0

    def __post_init__(self) -> None:
        for name in ("pose_delay_ns", "imu_delay_ns"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 0):
                raise ValueError(f"log config {name!r} must be an integer >= 0, got {value!r}")


def _delivery(t_ns: IntArray, delay_ns: int) -> IntArray:
    """Delivery time of each sample (stamps ascending, as the loader orders them)."""
    return t_ns + delay_ns


class LogPoseSource:
    """Recorded poses, delivered once the clock has passed their delivery time."""

    def __init__(self, clock: SimClock, stream: Series, delay_ns: int) -> None:
        self._clock = clock
        self._stream = stream
        self._due = _delivery(stream.t_ns, delay_ns)
        self._next = 0

    def poll(self) -> list[PoseSample]:
        """Return the poses delivered since the last call, in recorded order."""
        end = int(np.searchsorted(self._due, self._clock.now_ns(), side="left"))
        t, v = self._stream.t_ns, self._stream.values
        out = [
            PoseSample(int(t[i]), float(v[i, 0]), float(v[i, 1]), float(v[i, 2]))
            for i in range(self._next, end)
        ]
        self._next = max(self._next, end)
        return out


class LogImuSource:
    """Recorded IMU samples, delivered once the clock has passed their delivery time."""

    def __init__(self, clock: SimClock, stream: Series, delay_ns: int) -> None:
        self._clock = clock
        self._stream = stream
        self._due = _delivery(stream.t_ns, delay_ns)
        self._next = 0

    def poll(self) -> list[ImuSample]:
        """Return the IMU samples delivered since the last call, in recorded order."""
        end = int(np.searchsorted(self._due, self._clock.now_ns(), side="left"))
        t, v = self._stream.t_ns, self._stream.values
        out = [
            ImuSample(int(t[i]), float(v[i, 0]), float(v[i, 1]), float(v[i, 2]))
            for i in range(self._next, end)
        ]
        self._next = max(self._next, end)
        return out


class LogObstacleSource:
    """The recorded obstacle layouts: the newest one stamped at or before now.

    Before the first recorded layout the first one is served (the recorder logs
    the layout the stack started with at its first tick).
    """

    def __init__(self, clock: SimClock, layouts: tuple[ObstacleLayout, ...]) -> None:
        if not layouts:
            raise LogDataError("the log holds no obstacle layout; the stack cannot run on it")
        self._clock = clock
        self._layouts = layouts
        self._t_ns = np.maximum.accumulate(np.array([x.t_ns for x in layouts], dtype=np.int64))

    def latest(self) -> ObstacleLayout:
        """Return the newest layout recorded at or before the clock's time."""
        i = int(in_force(self._t_ns, self._clock.now_ns())[0])
        return self._layouts[max(i, 0)]


class CapturingThrusterSink:
    """Captures the commands the stack sends; fails where the recording's link failed.

    Args:
        failures_ns: Command times (ns) at which delivery failed in the recording.
    """

    def __init__(self, failures_ns: frozenset[int] = frozenset()) -> None:
        self.commands: list[ThrusterCommand] = []
        self._failures_ns = failures_ns

    def send(self, command: ThrusterCommand) -> None:
        """Capture `command`, or raise ThrusterSinkError where the recording failed."""
        if command.t_ns in self._failures_ns:
            raise ThrusterSinkError(f"thruster link failed at t={command.t_ns} ns in the recording")
        self.commands.append(command)

    def as_array(self) -> tuple[IntArray, FloatArray]:
        """Return the captured (t_ns (N,), commands (N, 5)) in the recorded stream's layout."""
        t = np.array([c.t_ns for c in self.commands], dtype=np.int64)
        values = np.array(
            [
                (c.tunnel, c.port, c.starboard, c.port_angle_rad, c.starboard_angle_rad)
                for c in self.commands
            ],
            dtype=np.float64,
        ).reshape(-1, 5)
        return t, values


class LogWorld:
    """A recorded run behind the adapters, on a simulated clock starting at 0.

    Args:
        run: The recorded run.
        config: Delivery delays.
    """

    def __init__(self, run: RunData, config: LogConfig | None = None) -> None:
        config = config or LogConfig()
        self.run = run
        self.clock = SimClock(0)
        self.pose = LogPoseSource(self.clock, run.pose, config.pose_delay_ns)
        self.imu = LogImuSource(self.clock, run.imu, config.imu_delay_ns)
        layouts = tuple(layout.as_obstacle_layout() for layout in run.layouts)
        self.obstacles = LogObstacleSource(self.clock, layouts)
        self.thrusters = CapturingThrusterSink(thruster_failures_ns(run))
