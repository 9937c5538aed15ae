"""The ``qtm`` pose backend: Qualisys Track Manager's real-time protocol, without ROS.

A :class:`QtmPoseSource` connects to QTM with the `qtm-rt` client (the ``qtm`` extra,
imported only when the source opens), finds the rigid body by name in the 6D parameters
(``The_6D/Body/Name``, index order), streams 6D frames at the camera rate
(``allframes``) and turns each into an arena pose (:class:`~hil.adapters.qtm_feed.QtmFeed`:
mm and rotation matrix in the lab's NED axes, the vessel config's transform, QTM's
timestamp mapped onto the run clock). The network runs in a thread of its own with its
own asyncio loop, so :meth:`QtmPoseSource.poll` never blocks the 20-Hz loop.

Reactions: a lost body (NaN) gives no sample (the runtime's pose timeout then holds the
vessel) and an event; frame-number gaps are counted as drops; a jump of QTM's clock
re-estimates the offset; a lost connection is retried with exponential backoff. Each is an
:class:`~hil.core.records.Event` with a ``qtm_*`` code, handed at each poll to the
source's ``on_event`` callback (for the run log: ``log.event(e.t_ns, e.level, e.code,
e.text)``) or kept for :meth:`QtmPoseSource.drain_events`, and counted in
:attr:`QtmPoseSource.counters`. The vessel config's ``[qtm]`` table becomes a
:class:`QtmConfig` through :func:`qtm_config_from_table`.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import threading
from collections.abc import Callable, Coroutine
from dataclasses import dataclass, field, replace
from typing import Any

from hil.adapters.frames import ArenaTransform
from hil.adapters.interfaces import Clock
from hil.adapters.qtm_feed import (
    ClockSettings,
    QtmCounters,
    QtmError,
    QtmFeed,
    body_index,
    yaw_from_rotation_matrix,
)
from hil.core.clock import read_beside
from hil.core.config import check_keys, from_table
from hil.core.qtm_sample import QtmSample
from hil.core.records import Event, EventLevel
from hil.core.samples import Frame, PoseSample

# Steady-clock time (ns) the reads around an arrival may span and still give the run
# clock's difference to it: more, and the network thread was held between them.
_STEADY_READ_NS = 1_000_000

DEFAULT_PORT = 22223
"""QTM's little-endian real-time port."""


@dataclass(frozen=True, slots=True)
class QtmConfig:
    """Where QTM is and how its feed is read (the vessel config's ``[qtm]`` table).

    Attributes:
        host: QTM computer's address.
        body: Name of the vessel's 6D rigid body in QTM.
        port: QTM's real-time port (the little-endian one).
        rate_hz: Frames per second asked of QTM; None: every camera frame (``allframes``).
        transform: Lab NED world and mocap body to the arena and the vessel's body origin.
        version: RT protocol version asked for.
        timeout_s: Time allowed for a connection and each command's answer (s).
        backoff_initial_s: Wait before the first reconnection attempt (s).
        backoff_max_s: Longest wait between attempts; the wait doubles up to it (s).
        clock: How QTM's timestamps map onto the run clock.
        stall_s: A silence of the stream longer than this (s) is a stall event.
    """

    host: str
    body: str
    port: int = DEFAULT_PORT
    rate_hz: int | None = None
    transform: ArenaTransform = field(default_factory=ArenaTransform)
    version: str = "1.25"
    timeout_s: float = 5.0
    backoff_initial_s: float = 0.1
    backoff_max_s: float = 5.0
    clock: ClockSettings = field(default_factory=ClockSettings)
    stall_s: float = 0.1

    def __post_init__(self) -> None:
        if not self.host or not self.body:
            raise ValueError(f"a QTM feed needs a host and a body, got {self.host!r}, "
                             f"{self.body!r}")
        if not 0 < self.port < 65536:
            raise ValueError(f"port must be 1..65535, got {self.port!r}")
        if self.rate_hz is not None and self.rate_hz < 1:
            raise ValueError(f"rate_hz must be a whole number >= 1 or None, got {self.rate_hz!r}")
        for name in ("timeout_s", "backoff_initial_s", "backoff_max_s", "stall_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be > 0 s, got {value!r}")

    @property
    def frames(self) -> str:
        """The ``streamframes`` argument: ``allframes`` or ``frequency:n``."""
        return "allframes" if self.rate_hz is None else f"frequency:{self.rate_hz}"


TABLE_KEYS = frozenset({"host", "port", "body", "rate_hz", "version", "timeout_s",
                        "backoff_initial_s", "backoff_max_s", "stall_s", "clock"})
"""Keys of the vessel config's ``[qtm]`` table (``[qtm.clock]`` holds ClockSettings)."""


def qtm_config_from_table(data: dict[str, Any], transform: ArenaTransform,
                          where: str = "qtm.") -> QtmConfig:
    """Build the qtm backend's settings from the vessel config's ``[qtm]`` table.

    The table holds ``host``, ``body`` (required), ``port`` (22223), ``rate_hz`` (absent:
    every camera frame) and optionally the timing keys of :class:`QtmConfig`; the lab
    transform is the vessel config's one (``[ros.transform]``), not repeated here.

    Args:
        data: The ``[qtm]`` table as read from TOML.
        transform: The lab NED world and mocap body to the arena.
        where: Path of the table with a trailing dot, for messages.

    Raises:
        hil.core.config.ConfigError: An unknown, missing or mistyped key, naming it.
    """
    check_keys(data, set(TABLE_KEYS), where)
    return replace(from_table(QtmConfig, data, where), transform=transform)


def _import_qtm_rt() -> Any:
    try:
        import qtm_rt
    except ImportError as err:
        raise QtmError("the qtm backend needs qtm-rt: install the 'qtm' extra "
                       f"(pip install -e '.[qtm]'; tools/dev.py does) ({err})") from err
    return qtm_rt


class QtmPoseSource:
    """Vessel poses from QTM's 6D stream, in the arena frame (a :class:`PoseSource`).

    Use as a context manager, or :meth:`open` and :meth:`close`. The source keeps trying
    to connect until it is closed: an unreachable QTM is events, not an exception.

    Args:
        config: Host, body, rate, transform and timing.
        clock: The run's clock; arrivals are read from it (from the network thread).
        on_event: Receives the feed's events at each :meth:`poll`, in the polling thread
            (e.g. ``lambda e: log.event(e.t_ns, e.level, e.code, e.text)``); None keeps
            them for :meth:`drain_events`.
        on_sample: Receives every 6D frame of the body as received (a
            :class:`~hil.core.qtm_sample.QtmSample`, lost bodies included) at each
            :meth:`poll`, before the poses, in the polling thread (e.g. the recorder's
            ``record``); None drops them.
        steady: A steady clock (ns, never set: :func:`time.monotonic_ns`) where `clock` is
            a system clock that can be set (the ROS clock on wall time): a step of `clock`
            then moves QTM's offset with it at once; None where `clock` cannot be set or
            is simulated time.
    """

    def __init__(self, config: QtmConfig, clock: Clock,
                 on_event: Callable[[Event], None] | None = None,
                 on_sample: Callable[[QtmSample], None] | None = None,
                 steady: Callable[[], int] | None = None) -> None:
        self.config = config
        self._clock = clock
        self._steady = steady
        self._on_event = on_event
        self._on_sample = on_sample
        self._feed = QtmFeed(config.body, config.transform, config.clock, config.stall_s)
        self._lock = threading.Lock()
        self._poses: list[PoseSample] = []
        self._first = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread: threading.Thread | None = None
        self._qtm_rt: Any = None

    # -- the stack's side ------------------------------------------------------------

    def open(self) -> QtmPoseSource:
        """Start the network thread (it connects, and reconnects, on its own).

        Raises:
            QtmError: qtm-rt is not installed.
        """
        if self._thread is not None:
            return self
        self._qtm_rt = _import_qtm_rt()
        # The conversion's numba kernels compile (or load) on first use: here, not on the
        # first frame in the network thread, which would sit on the stream for that long.
        self._feed.transform.to_arena(PoseSample(0, 0.0, 0.0, yaw_from_rotation_matrix(
            (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)), Frame.LAB_NED))
        self._loop = asyncio.new_event_loop()
        ready = threading.Event()
        self._thread = threading.Thread(target=self._run_loop, args=(ready,), name="hil-qtm",
                                        daemon=True)
        self._thread.start()
        ready.wait()
        return self

    def close(self) -> None:
        """Stop streaming, disconnect and end the network thread."""
        loop, thread = self._loop, self._thread
        if loop is None or thread is None:
            return
        stop = self._stop
        if stop is not None:
            loop.call_soon_threadsafe(stop.set)
        thread.join(timeout=self.config.timeout_s + 2.0)
        self._loop = self._thread = None

    def __enter__(self) -> QtmPoseSource:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _check_open(self) -> None:
        if self._thread is None:
            raise QtmError("the QTM pose source is not open")

    def poll(self) -> list[PoseSample]:
        """Return the arena poses received since the last call, oldest first.

        With an ``on_event`` callback, the events since the last call go to it first.
        """
        self._check_open()
        now_ns = self._clock.now_ns()
        with self._lock:
            self._feed.watch(now_ns)
            out, self._poses = self._poses, []
            samples, self._feed.samples = self._feed.samples, []
        if self._on_sample is not None:
            for sample in samples:
                self._on_sample(sample)
        if self._on_event is not None:
            for event in self.drain_events():
                self._on_event(event)
        return sorted(out, key=lambda s: s.t_ns)

    def drain_events(self) -> list[Event]:
        """Return the feed's events since the last call, oldest first (codes ``qtm_*``)."""
        with self._lock:
            out, self._feed.events = self._feed.events, []
        return out

    @property
    def counters(self) -> QtmCounters:
        """What the feed counted so far (frames, poses, losses, drops, jumps, links)."""
        with self._lock:
            return self._feed.counts

    @property
    def offset_ns(self) -> int | None:
        """The clock offset in force: run time = QTM time + offset (ns); None before a frame."""
        with self._lock:
            return self._feed.clock.offset_ns

    def wait_first(self, timeout_s: float) -> bool:
        """Wait up to `timeout_s` (s) for the first pose (kept for :meth:`poll`)."""
        return self._first.wait(timeout_s)

    # -- the network thread ----------------------------------------------------------

    def _event(self, level: EventLevel, code: str, text: str, **counts: int) -> None:
        with self._lock:
            self._feed.event(self._clock.now_ns(), level, code, text, **counts)

    def _run_loop(self, ready: threading.Event) -> None:
        loop = self._loop
        assert loop is not None
        asyncio.set_event_loop(loop)
        self._stop = asyncio.Event()
        ready.set()
        try:
            loop.run_until_complete(self._serve())
        finally:
            pending = asyncio.all_tasks(loop)
            for task in pending:
                task.cancel()
            loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    async def _serve(self) -> None:
        """Connect, stream until the link drops, wait, and again, until stopped."""
        cfg = self.config
        delay_s = cfg.backoff_initial_s
        stop = self._stop
        assert stop is not None
        while not stop.is_set():
            streamed = await self._session()
            if stop.is_set():
                break
            if streamed:
                delay_s = cfg.backoff_initial_s
            self._event(EventLevel.INFO, "qtm_retry",
                        f"reconnecting to {cfg.host}:{cfg.port} in {delay_s:.2f} s")
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stop.wait(), delay_s)
            delay_s = min(2.0 * delay_s, cfg.backoff_max_s)

    async def _session(self) -> bool:
        """Run one connection; return whether it reached streaming."""
        cfg = self.config
        loop = asyncio.get_running_loop()
        lost: asyncio.Future[object] = loop.create_future()

        def on_disconnect(exc: object) -> None:
            if not lost.done():
                lost.set_result(exc)

        where = f"{cfg.host}:{cfg.port}"
        conn, why = await self._connect(lost, on_disconnect)
        if conn is None:
            self._event(EventLevel.WARN, "qtm_connect_failed",
                        f"cannot connect to QTM at {where}: {why}", connect_failures=1)
            return False
        try:
            index = await self._start_stream(conn, lost)
        except (QtmError, TimeoutError, self._qtm_rt.QRTCommandException) as err:
            self._event(EventLevel.ERROR, "qtm_connect_failed",
                        f"QTM at {where} cannot stream body {cfg.body!r}: {err}",
                        connect_failures=1)
            _disconnect(conn)
            return False
        self._event(EventLevel.INFO, "qtm_connected",
                    f"streaming body {cfg.body!r} (6D index {index}) from {where}, "
                    f"{cfg.frames}", connects=1)
        return await self._stream_until_lost(conn, lost, where)

    async def _connect(self, lost: asyncio.Future[object],
                       on_disconnect: Callable[[object], None]) -> tuple[Any, str]:
        """Open the link and set the protocol version; return (connection or None, why not).

        As qtm-rt's ``connect()`` does, with the classes it builds (QTMProtocol,
        QRTConnection); but ``connect()`` waits for the version's answer without a timeout,
        on past a link QTM closed, and leaves the socket open when it fails. Here each step
        has the timeout, and a failed link is closed.
        """
        cfg = self.config
        loop = asyncio.get_running_loop()
        protocol_class = self._qtm_rt.protocol.QTMProtocol
        try:
            transport, protocol = await asyncio.wait_for(loop.create_connection(
                lambda: protocol_class(loop=loop, on_disconnect=on_disconnect),
                cfg.host, cfg.port), cfg.timeout_s)
        except (OSError, TimeoutError) as err:
            return None, str(err) or type(err).__name__
        versioned: asyncio.Future[Any] = asyncio.ensure_future(
            protocol.set_version(cfg.version))
        await asyncio.wait([versioned, lost], timeout=cfg.timeout_s,
                           return_when=asyncio.FIRST_COMPLETED)
        if not versioned.done():
            versioned.cancel()
            why = ("QTM closed the link" if lost.done() else
                   f"no answer to 'version {cfg.version}' within {cfg.timeout_s:g} s")
        elif versioned.exception() is not None:
            why = f"version {cfg.version} refused: {versioned.exception()}"
        elif lost.done():
            why = "QTM closed the link"
        else:
            return self._qtm_rt.QRTConnection(protocol, timeout=cfg.timeout_s), ""
        transport.close()
        return None, why

    async def _start_stream(self, conn: Any, lost: asyncio.Future[object]) -> int:
        cfg = self.config
        xml = await conn.get_parameters(["6d"])
        index = body_index(xml, cfg.body)
        with self._lock:
            self._feed.restart()
        on_packet = self._packet_handler(index)
        # qtm-rt resolves streamframes with the first data frame (QTM sends no answer);
        # none within the timeout means QTM is not measuring: wait on for the link anyway.
        started: asyncio.Future[object] = asyncio.ensure_future(conn.stream_frames(
            frames=cfg.frames, components=["6d"], on_packet=on_packet))
        await asyncio.wait([started, lost], return_when=asyncio.FIRST_COMPLETED)
        if not started.done():
            started.cancel()
        elif isinstance(started.exception(), TimeoutError):
            self._event(EventLevel.WARN, "qtm_stall",
                        f"no frame within {cfg.timeout_s:g} s of asking QTM to stream")
        elif started.exception() is not None:
            raise QtmError(f"streamframes failed: {started.exception()}")
        return index

    async def _stream_until_lost(self, conn: Any, lost: asyncio.Future[object],
                                 where: str) -> bool:
        stop = self._stop
        assert stop is not None
        stopping: asyncio.Future[object] = asyncio.ensure_future(stop.wait())
        await asyncio.wait([lost, stopping], return_when=asyncio.FIRST_COMPLETED)
        stopping.cancel()
        if lost.done():
            with self._lock:
                self._feed.restart()  # no stream: silence is no stall
            self._event(EventLevel.WARN, "qtm_disconnected",
                        f"lost the link to QTM at {where} ({lost.result() or 'closed'})",
                        disconnects=1)
            return True
        if conn.has_transport():
            await _maybe(conn.stream_frames_stop())
        _disconnect(conn)
        return True

    def _packet_handler(self, index: int) -> Callable[[Any], None]:
        feed, clock, lock, steady = self._feed, self._clock, self._lock, self._steady

        def on_packet(packet: Any) -> None:
            steady_ns: int | None = None
            if steady is None:
                arrival_ns = clock.now_ns()
            else:
                arrival_ns, steady_ns, span_ns = read_beside(clock.now_ns, steady)
                if span_ns > _STEADY_READ_NS:
                    steady_ns = None  # held between every pair of reads: none to trust
            got = packet.get_6d()
            with lock:
                if got is None or index >= len(got[1]):
                    feed.event(arrival_ns, EventLevel.WARN, "qtm_no_body",
                               f"frame {packet.framenumber} has no 6D body {index}")
                    return
                info, bodies = got
                position, rotation = bodies[index]
                pose = feed.frame(arrival_ns, packet.timestamp, packet.framenumber,
                                  (position.x, position.y, position.z), rotation.matrix,
                                  info.drop_rate, info.out_of_sync_rate, index, steady_ns)
                if pose is not None:
                    self._poses.append(pose)
            if pose is not None:
                self._first.set()

        return on_packet


async def _maybe(call: Coroutine[Any, Any, object]) -> None:
    with contextlib.suppress(TimeoutError, OSError, RuntimeError):
        await asyncio.wait_for(call, 1.0)


def _disconnect(conn: Any) -> None:
    if conn.has_transport():
        conn.disconnect()

