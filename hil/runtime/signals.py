"""SIGINT and SIGTERM routed to a clean stop of the loop, not an exception mid-tick.

A Ctrl-C that raised KeyboardInterrupt inside a tick would leave the thrusters at their
last command and the log without its end; routed to :meth:`Runtime.request_stop`, the
loop brakes from its next tick to rest, then sends zero thrust, and records why (a
``stopped`` event), so an interrupted run is a complete log that replays as interrupted.
Every signal is routed: a second one while braking cuts the thrust at once.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType

__all__ = ["stop_on_signals"]


@contextmanager
def stop_on_signals(stop: Callable[[str], None]) -> Iterator[None]:
    """Route SIGINT and SIGTERM to ``stop("stopped by SIGINT")`` inside the block.

    Off the main thread (where Python cannot install handlers) the block runs unchanged.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, _frame: FrameType | None) -> None:
        stop(f"stopped by {signal.Signals(signum).name}")

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
