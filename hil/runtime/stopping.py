"""Why a run stops, and the braking to rest that follows every stop.

Three things stop a run: an abort (no safe input, a lost controller, a broken
premise), the operator's request (SIGINT / SIGTERM) and the time limit. Each is a
safe stop: the loop flies velocity zero under the low level until the estimate is at
rest (|u|, |v| <= :data:`REST_SPEED_MPS`, |r| <= :data:`REST_YAW_RATE_RADPS` for
:data:`REST_HOLD_S`), then cuts the thrust; a second request while braking cuts it at
once (the emergency stop), as does braking past :data:`MAX_BRAKE_S`.
"""

from __future__ import annotations

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.records import EventLevel
from hil.runtime.events import EventCode
from hil.runtime.feed import EventSink
from hil.runtime.settings import NS_PER_S
from hil.runtime.stats import RunStats

__all__ = [
    "MAX_BRAKE_S",
    "REST_HOLD_S",
    "REST_SPEED_MPS",
    "REST_YAW_RATE_RADPS",
    "Stopping",
]

REST_SPEED_MPS = 0.01
"""At rest: |u| and |v| of the estimate at most this (m/s)..."""
REST_YAW_RATE_RADPS = 0.01
"""... and |r| at most this (rad/s) ..."""
REST_HOLD_S = 1.0
"""... for this long (s): then braking ends with thrusters at zero."""
MAX_BRAKE_S = 8.0
"""Braking longer than this (s) ends with thrusters at zero and a warning: from the
fastest input (0.2 m/s) the vessel is at rest within about 4 s under the low level."""


class Stopping:
    """The stop requests, the abort reason and the braking in progress.

    Args:
        stats: Where the braking time is counted.
        event: Records how braking ended.
    """

    def __init__(self, stats: RunStats, event: EventSink) -> None:
        self._stats = stats
        self._event = event
        self.requested: str | None = None
        """The reason of the operator's last stop request (None: none)."""
        self.requests = 0
        """How many stop requests came."""
        self.abort: str | None = None
        """Why the run must abort (None: it need not)."""
        self._requests_at_brake = 0
        self._since_ns = 0
        self._rest_since_ns: int | None = None

    def request(self, reason: str) -> None:
        """Note an operator's stop request (safe from a signal handler)."""
        self.requested = reason
        self.requests += 1

    def due(self, t_ns: int, start_ns: int, max_duration_s: float) -> tuple[EventCode, str] | None:
        """Return the stop due now (its event code and reason), abort first; None: go on."""
        if self.abort is not None:
            return EventCode.ABORTED, self.abort
        if self.requested is not None:
            return EventCode.STOPPED, self.requested
        if t_ns - start_ns > max_duration_s * NS_PER_S:
            return EventCode.TIMEOUT, f"not docked after {max_duration_s:.0f} s"
        return None

    def start_braking(self, t_ns: int) -> None:
        """Start braking at `t_ns`; only a request after this one cuts it short."""
        self._since_ns = t_ns
        self._rest_since_ns = None
        self._requests_at_brake = self.requests

    def cut_short(self, t_ns: int, pose_ok: bool) -> bool:
        """Return whether braking must end at once (thrust cut), and say why.

        A second stop request while braking (the operator's emergency stop), or no
        fresh pose (`pose_ok` False: the loop cannot brake blind).
        """
        if self.requests > self._requests_at_brake:
            self._event(t_ns, EventLevel.WARN, EventCode.STOPPED,
                        f"{self.requested} again while braking: thrust cut at once")
            return True
        if not pose_ok:
            self._event(t_ns, EventLevel.ERROR, EventCode.POSE_LOST,
                        f"no pose while braking ({self.braking_s(t_ns):.1f} s in): thrust cut")
            return True
        return False

    def braking_s(self, t_ns: int) -> float:
        """Return how long the vessel has been braking at `t_ns` (s)."""
        return (t_ns - self._since_ns) / NS_PER_S

    def brake(self, t_ns: int, nu_hat: FloatArray) -> bool:
        """Judge one tick of braking on the estimated velocity `nu_hat` (u, v, r), (3,).

        Returns:
            True: keep flying velocity zero. False: at rest for :data:`REST_HOLD_S`, or
            braking past :data:`MAX_BRAKE_S` (a warning): thrusters to zero.
        """
        resting = bool(
            abs(nu_hat[0]) <= REST_SPEED_MPS and abs(nu_hat[1]) <= REST_SPEED_MPS
            and abs(nu_hat[2]) <= REST_YAW_RATE_RADPS
        )
        if not resting:
            self._rest_since_ns = None
        elif self._rest_since_ns is None:
            self._rest_since_ns = t_ns
        since_s = self.braking_s(t_ns)
        if self._rest_since_ns is not None and (
            t_ns - self._rest_since_ns >= REST_HOLD_S * NS_PER_S
        ):
            self._event(t_ns, EventLevel.INFO, EventCode.AT_REST,
                        f"at rest {since_s:.1f} s after the stop: thrusters to zero")
        elif since_s > MAX_BRAKE_S:
            self._event(t_ns, EventLevel.WARN, EventCode.AT_REST,
                        f"not at rest after {MAX_BRAKE_S:g} s of braking (estimate "
                        f"{np.round(nu_hat, 3).tolist()}): thrusters to zero")
        else:
            return True
        self._stats.brake_s = since_s
        return False
