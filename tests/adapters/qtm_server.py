"""A QTM real-time server for the tests: asyncio on loopback, written from the protocol.

It speaks what `qtm-rt` and the ``qtm`` backend use of QTM's RT protocol (little-endian
TCP): packets ``<u32 size incl. the 8-byte header, u32 type>`` (0 error, 1 command, 2 XML,
3 data, 6 event); the greeting "QTM RT Interface connected"; ``version``, ``qtmversion``,
``byteorder``, ``getstate`` (an event packet), ``getparameters 6d`` (XML with the bodies'
names), ``streamframes allframes|frequency:n 6d [6deuler]`` (data packets, no answer) and
``streamframes stop``. A data packet is ``<q I I>`` (timestamp us, frame number, component
count), per component ``<I I>`` (size incl. that header, type 5 = 6D, 6 = 6D Euler) and
``<i h h>`` (bodies, drop rate, out-of-sync rate), then per body 3 f32 position (mm) and
9 f32 rotation matrix, column by column (6D) or 3 f32 Euler angles roll, pitch, yaw (deg;
QTM's default x-y-z definition, 6D Euler).

The tracked body follows a trajectory (a callable: server time s -> (north m, east m, yaw
rad) in the lab's NED axes), at `rate_hz`, frame n due at n / rate_hz of server time (s
since the first ``streamframes``). Faults are injected by server time: NaN spans of the
body, stalls (silence; frames due meanwhile are never sent, as QTM skips frames a client
cannot take), dropped frame numbers, jumps of the QTM clock, disconnects and refused
connections.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import struct
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

Trajectory = Callable[[float], tuple[float, float, float]]
"""Server time (s) -> the tracked body's (north m, east m, yaw rad) in the lab frame."""

HEADER = struct.Struct("<II")
DATA_HEADER = struct.Struct("<qII")
COMPONENT_HEADER = struct.Struct("<II")
COMPONENT_6D = struct.Struct("<ihh")
BODY_6D = struct.Struct("<12f")
BODY_6D_EULER = struct.Struct("<6f")
TYPE_ERROR, TYPE_COMMAND, TYPE_XML, TYPE_DATA, TYPE_EVENT = 0, 1, 2, 3, 6
COMPONENT_TYPES = {"6d": 5, "6deuler": 6}
EVENT_CONNECTED = 1
GREETING = "QTM RT Interface connected"
QTM_VERSION = "QTM Version is 2024.2 (build 13840)"
HULL_HEIGHT_MM = -120.0  # the marker plate's z (mm, down positive: above the water)


@dataclass(frozen=True)
class Faults:
    """What goes wrong, by server time (s since the first ``streamframes``).

    Attributes:
        nan_s: Spans [start, stop) in which the tracked body is lost (NaN).
        stall_s: Spans [start, stop) in which nothing is sent; frames due are skipped.
        drop_frames: Frame numbers never sent.
        clock_jumps_s: (at, jump): from `at` on QTM's timestamps are `jump` later (s).
        disconnect_at_s: Times at which the client's connection is cut (each once).
        refuse_first: This many connections are closed as soon as they are accepted.
        silent_first: This many connections (after the refused) get no answer at all.
    """

    nan_s: tuple[tuple[float, float], ...] = ()
    stall_s: tuple[tuple[float, float], ...] = ()
    drop_frames: frozenset[int] = frozenset()
    clock_jumps_s: tuple[tuple[float, float], ...] = ()
    disconnect_at_s: tuple[float, ...] = ()
    refuse_first: int = 0
    silent_first: int = 0


def _inside(t_s: float, spans: Sequence[tuple[float, float]]) -> bool:
    return any(a <= t_s < b for a, b in spans)


def rotation_matrix(yaw_rad: float, pitch_rad: float = 0.0, roll_rad: float = 0.0) -> list[float]:
    """Return R = Rz(yaw) Ry(pitch) Rx(roll) as QTM sends it: 9 floats, column by column."""
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    rows = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    return [rows[i][j] for j in range(3) for i in range(3)]


def packet(kind: int, payload: bytes) -> bytes:
    """Return one RT packet: the header (size incl. itself, type) and the payload."""
    return HEADER.pack(HEADER.size + len(payload), kind) + payload


def text_packet(kind: int, text: str) -> bytes:
    """Return a command, error or XML packet (NUL-terminated text)."""
    return packet(kind, text.encode() + b"\0")


def parameters_xml(bodies: Sequence[str]) -> str:
    """Return QTM's 6D parameters (RT protocol 1.25 layout) naming `bodies` in index order."""
    entries = "".join(
        f"<Body><Name>{name}</Name><Enabled>true</Enabled>"
        f'<Color R="255" G="0" B="0"/><MaxResidual>10</MaxResidual>'
        f'<Points><Point X="0" Y="0" Z="0" Virtual="0" PhysicalId="0" Name="{name}_1"/>'
        "</Points></Body>"
        for name in bodies
    )
    return (
        '<?xml version="1.0" encoding="UTF-8"?><QTM_Parameters_Ver_1.25><The_6D>'
        f"<Bodies>{len(bodies)}</Bodies>{entries}"
        "<Euler><First>X</First><Second>Y</Second><Third>Z</Third></Euler>"
        "</The_6D></QTM_Parameters_Ver_1.25>"
    )


def data_packet(timestamp_us: int, frame: int, components: Sequence[str],
                bodies: Sequence[tuple[float, float, float, list[float]] | None],
                drop_rate: int = 0) -> bytes:
    """Return one data packet with the 6D (and/or 6D Euler) component of `bodies`.

    Args:
        timestamp_us: QTM's timestamp (us).
        frame: Frame number.
        components: "6d" and/or "6deuler", in order.
        bodies: Per body (x mm, y mm, z mm, matrix of 9 column-major floats), or None for
            a lost body (all NaN).
        drop_rate: The component's drop rate field.
    """
    parts = []
    for name in components:
        body_bytes = bytearray()
        for body in bodies:
            if body is None:
                count = 12 if name == "6d" else 6
                body_bytes += struct.pack(f"<{count}f", *([math.nan] * count))
                continue
            x, y, z, m = body
            if name == "6d":
                body_bytes += BODY_6D.pack(x, y, z, *m)
            else:
                roll = math.atan2(m[5], m[8])  # R32, R33
                pitch = -math.asin(max(-1.0, min(1.0, m[2])))  # -R31
                yaw = math.atan2(m[1], m[0])  # R21, R11
                body_bytes += BODY_6D_EULER.pack(
                    x, y, z, *(math.degrees(a) for a in (roll, pitch, yaw)))
        content = COMPONENT_6D.pack(len(bodies), drop_rate, 0) + bytes(body_bytes)
        parts.append(COMPONENT_HEADER.pack(COMPONENT_HEADER.size + len(content),
                                           COMPONENT_TYPES[name]) + content)
    return packet(TYPE_DATA,
                  DATA_HEADER.pack(timestamp_us, frame, len(parts)) + b"".join(parts))


@dataclass
class _Stream:
    components: list[str]
    every: int
    task: asyncio.Task[None] | None = None


@dataclass
class ServerLog:
    """What the server saw and did (read by the tests)."""

    commands: list[str] = field(default_factory=list)
    connections: int = 0
    refused: int = 0
    frames_sent: int = 0
    disconnects: int = 0


class QtmTestServer:
    """A QTM RT server on 127.0.0.1 (an ephemeral port) in a thread of its own.

    Args:
        trajectory: The tracked body's lab pose over server time.
        body: The tracked body's name.
        others: Names of the other 6D bodies (index order: others[:k], body, others[k:]
            with k = `body_index`).
        body_index: Index of the tracked body among the bodies.
        rate_hz: Camera frame rate.
        faults: What goes wrong when.
        clock_base_s: QTM's clock reads this at server time 0 (s).
        tilt_rad: Constant (pitch, roll) of the tracked body (rad).
        stepped: Server time is what :meth:`advance_to` last set (a simulated camera in
            lockstep with a simulated world), not wall time since the first stream.
    """

    def __init__(self, trajectory: Trajectory, body: str = "2", others: Sequence[str] = ("1",),
                 body_index: int = 1, rate_hz: float = 100.0, faults: Faults | None = None,
                 clock_base_s: float = 1000.0,
                 tilt_rad: tuple[float, float] = (0.0, 0.0), stepped: bool = False) -> None:
        self.trajectory = trajectory
        names = list(others)
        names.insert(body_index, body)
        self.bodies = tuple(names)
        self.body_index = body_index
        self.rate_hz = rate_hz
        self.faults = faults or Faults()
        self.clock_base_s = clock_base_s
        self.tilt_rad = tilt_rad
        self.stepped = stepped
        self._stepped_s = 0.0
        self._step: asyncio.Event | None = None
        self._sent = threading.Condition()
        self._next_due_s = -math.inf
        self.log = ServerLog()
        self.port = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._server: asyncio.Server | None = None
        self._start: float | None = None
        self._writers: set[asyncio.StreamWriter] = set()
        self._disconnects_done: set[float] = set()

    # -- control from the test's thread -----------------------------------------------

    def start(self) -> QtmTestServer:
        """Listen on an ephemeral loopback port (:attr:`port`) and start the clock."""
        self._loop = asyncio.new_event_loop()
        ready = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(ready,), daemon=True,
                                        name="qtm-test-server")
        self._thread.start()
        if not ready.wait(5.0):
            raise RuntimeError("the QTM test server did not start")
        return self

    def stop(self) -> None:
        """Close every connection and the listener; end the thread."""
        loop, thread = self._loop, self._thread
        if loop is None or thread is None:
            return
        asyncio.run_coroutine_threadsafe(self._shutdown(), loop).result(5.0)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(5.0)
        self._loop = self._thread = None

    def __enter__(self) -> QtmTestServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def start_monotonic_s(self) -> float | None:
        """`time.monotonic()` at server time 0; None before the first ``streamframes``."""
        return self._start

    def now_s(self) -> float:
        """Return server time: s since the first ``streamframes`` (0 before it)."""
        if self.stepped:
            return self._stepped_s
        return 0.0 if self._start is None else time.monotonic() - self._start

    def advance_to(self, t_s: float) -> None:
        """Stepped: move server time to `t_s` (s); the frames due by then go out."""
        loop, step = self._loop, self._step
        assert self.stepped
        assert loop is not None
        assert step is not None
        self._stepped_s = t_s
        loop.call_soon_threadsafe(step.set)

    def wait_sent(self, t_s: float, timeout_s: float = 5.0) -> bool:
        """Stepped: wait (wall time) until every frame due by `t_s` has been written."""
        with self._sent:
            return self._sent.wait_for(lambda: self._next_due_s > t_s, timeout_s)

    # -- the server's thread --------------------------------------------------------

    def _run(self, ready: threading.Event) -> None:
        loop = self._loop
        assert loop is not None
        asyncio.set_event_loop(loop)
        self._server = loop.run_until_complete(
            asyncio.start_server(self._client, "127.0.0.1", 0))
        self.port = self._server.sockets[0].getsockname()[1]
        self._step = asyncio.Event()
        ready.set()
        try:
            loop.run_forever()
        finally:
            pending = asyncio.all_tasks(loop)
            for task in pending:
                task.cancel()
            loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
            loop.close()

    async def _shutdown(self) -> None:
        assert self._server is not None
        self._server.close()
        for writer in list(self._writers):
            writer.close()
        await self._server.wait_closed()

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if self.log.refused < self.faults.refuse_first:
            self.log.refused += 1
            writer.close()
            return
        self.log.connections += 1
        self._writers.add(writer)
        silent = self.log.connections <= self.faults.silent_first
        writer.write(text_packet(TYPE_COMMAND, GREETING))
        stream = _Stream([], 1)
        try:
            while True:
                size, _kind = HEADER.unpack(await reader.readexactly(HEADER.size))
                body = await reader.readexactly(size - HEADER.size)
                if silent:
                    continue
                self._command(body.rstrip(b"\0").decode(), writer, stream)
        except (asyncio.IncompleteReadError, ConnectionError):
            pass
        finally:
            if stream.task is not None:
                stream.task.cancel()
            self._writers.discard(writer)
            writer.close()

    def _command(self, command: str, writer: asyncio.StreamWriter, stream: _Stream) -> None:
        self.log.commands.append(command)
        words = command.split()
        verb = words[0].lower() if words else ""
        if verb == "version" and len(words) == 2:
            ok = words[1] in {"1.25", "1.24", "1.23", "1.22", "1.21", "1.20", "1.19", "1.18"}
            writer.write(text_packet(TYPE_COMMAND, f"Version set to {words[1]}") if ok else
                         text_packet(TYPE_ERROR, "Version NOT supported"))
        elif verb == "qtmversion":
            writer.write(text_packet(TYPE_COMMAND, QTM_VERSION))
        elif verb == "byteorder":
            writer.write(text_packet(TYPE_COMMAND, "Byte order is little endian"))
        elif verb == "getstate":
            writer.write(packet(TYPE_EVENT, bytes([EVENT_CONNECTED])))
        elif verb == "getparameters" and [w.lower() for w in words[1:]] in (["6d"], ["all"]):
            writer.write(text_packet(TYPE_XML, parameters_xml(self.bodies)))
        elif verb == "streamframes" and len(words) >= 2 and words[1].lower() == "stop":
            if stream.task is not None:
                stream.task.cancel()
                stream.task = None
        elif verb == "streamframes" and len(words) >= 3 and self._stream_args(words, stream):
            if stream.task is not None:
                stream.task.cancel()
            if self._start is None:
                self._start = time.monotonic()
            stream.task = asyncio.ensure_future(self._stream(writer, stream))
        else:
            writer.write(text_packet(TYPE_ERROR, f"Parse error: {command!r}"))

    def _stream_args(self, words: list[str], stream: _Stream) -> bool:
        frames = words[1].lower()
        components = [w.lower() for w in words[2:]]
        if any(c not in COMPONENT_TYPES for c in components):
            return False
        if frames == "allframes":
            every = 1
        elif frames.startswith("frequency:"):
            every = max(1, round(self.rate_hz / float(frames.split(":", 1)[1])))
        else:
            return False
        stream.components, stream.every = components, every
        return True

    def frame_at(self, frame: int) -> tuple[int, list[tuple[float, float, float, list[float]]
                                                      | None]]:
        """Return QTM's timestamp (us) and the bodies of frame number `frame`."""
        t_s = frame / self.rate_hz
        jump_s = sum(j for at, j in self.faults.clock_jumps_s if t_s >= at)
        timestamp_us = round((self.clock_base_s + t_s + jump_s) * 1e6)
        bodies: list[tuple[float, float, float, list[float]] | None] = []
        for index in range(len(self.bodies)):
            if index != self.body_index:
                bodies.append((1000.0 * index, -500.0, HULL_HEIGHT_MM, rotation_matrix(0.0)))
            elif _inside(t_s, self.faults.nan_s):
                bodies.append(None)
            else:
                north_m, east_m, yaw_rad = self.trajectory(t_s)
                pitch, roll = self.tilt_rad
                bodies.append((north_m * 1000.0, east_m * 1000.0, HULL_HEIGHT_MM,
                               rotation_matrix(yaw_rad, pitch, roll)))
        return timestamp_us, bodies

    async def _stream(self, writer: asyncio.StreamWriter, stream: _Stream) -> None:
        with contextlib.suppress(ConnectionError):
            await self._frames(writer, stream)

    async def _frames(self, writer: asyncio.StreamWriter, stream: _Stream) -> None:
        now_frames = self.now_s() * self.rate_hz
        frame = math.ceil(now_frames) if self.stepped else math.floor(now_frames) + 1
        while not writer.is_closing():
            due_s = frame / self.rate_hz
            with self._sent:
                self._next_due_s = due_s
                self._sent.notify_all()
            await self._until(due_s)
            if self._cut(due_s, writer):
                return
            if (frame % stream.every == 0 and frame not in self.faults.drop_frames
                    and not _inside(due_s, self.faults.stall_s)):
                timestamp_us, bodies = self.frame_at(frame)
                writer.write(data_packet(timestamp_us, frame, stream.components, bodies))
                self.log.frames_sent += 1
                await writer.drain()
            frame += 1

    async def _until(self, due_s: float) -> None:
        if not self.stepped:
            wait_s = due_s - self.now_s()
            if wait_s > 0:
                await asyncio.sleep(wait_s)
            return
        assert self._step is not None
        while self.now_s() < due_s:
            self._step.clear()
            if self.now_s() >= due_s:
                break
            await self._step.wait()

    def _cut(self, t_s: float, writer: asyncio.StreamWriter) -> bool:
        for at in self.faults.disconnect_at_s:
            if t_s >= at and at not in self._disconnects_done:
                self._disconnects_done.add(at)
                self.log.disconnects += 1
                with contextlib.suppress(OSError):
                    writer.transport.abort()
                return True
        return False
