"""The test QTM server against the real qtm-rt client: what the library expects of QTM."""

from __future__ import annotations

import asyncio
import itertools
import math
import socket
from collections.abc import Iterator
from typing import Any

import pytest

from hil.adapters.qtm_feed import body_names
from tests.adapters.qtm_server import (
    HEADER,
    HULL_HEIGHT_MM,
    QTM_VERSION,
    TYPE_COMMAND,
    TYPE_ERROR,
    Faults,
    QtmTestServer,
    data_packet,
    rotation_matrix,
)

qtm_rt = pytest.importorskip("qtm_rt")

from qtm_rt.packet import QRTPacket  # noqa: E402  (after the skip)


def line(t_s: float) -> tuple[float, float, float]:
    return 1.0 + 0.2 * t_s, -2.0 + 0.1 * t_s, 0.5 - 0.3 * t_s


@pytest.fixture
def server() -> Iterator[QtmTestServer]:
    with QtmTestServer(line, body="2", others=("1", "3"), body_index=1,
                       faults=Faults(nan_s=((0.0, 0.05),)), tilt_rad=(0.1, -0.2)) as srv:
        yield srv


async def _session(port: int, components: list[str], frames: str = "allframes"
                   ) -> tuple[list[Any], list[Any]]:
    conn = await qtm_rt.connect("127.0.0.1", port=port, version="1.25", timeout=2)
    assert conn is not None
    answers = [await conn.qtm_version(), await conn.byte_order(), await conn.get_state(),
               await conn.get_parameters(["6d"])]
    packets: list[Any] = []
    assert await conn.stream_frames(frames=frames, components=components,
                                    on_packet=packets.append) == b"Ok"
    await asyncio.sleep(0.25)
    await conn.stream_frames_stop()
    await asyncio.sleep(0.05)
    conn.disconnect()
    return answers, packets


def test_qtm_rt_connects_and_reads_the_parameters(server: QtmTestServer) -> None:
    answers, _ = asyncio.run(_session(server.port, ["6d"]))
    version, order, state, xml = answers
    assert version == QTM_VERSION.encode()
    assert order == b"Byte order is little endian"
    assert state == qtm_rt.QRTEvent.EventConnected
    assert body_names(xml) == ["1", "2", "3"]
    assert server.log.commands[:6] == ["version 1.25", "qtmversion", "byteorder", "getstate",
                                       "getparameters 6d", "streamframes allframes 6d"]
    assert server.log.commands[-1] == "streamframes stop"


def test_qtm_rt_reads_6d_frames_of_the_trajectory(server: QtmTestServer) -> None:
    _, packets = asyncio.run(_session(server.port, ["6d", "6deuler"]))
    assert len(packets) >= 10
    numbers = [p.framenumber for p in packets]
    assert numbers == list(range(numbers[0], numbers[0] + len(numbers)))
    for p in packets:
        t_s = p.framenumber / server.rate_hz
        assert p.timestamp == round((server.clock_base_s + t_s) * 1e6)
        info, bodies = p.get_6d()
        assert (info.body_count, info.drop_rate, info.out_of_sync_rate) == (3, 0, 0)
        position, rotation = bodies[1]
        if t_s < 0.05:  # the injected loss: every float NaN
            assert math.isnan(position.x)
            assert all(math.isnan(v) for v in rotation.matrix)
            continue
        north, east, yaw = line(t_s)
        assert (position.x, position.y, position.z) == pytest.approx(
            (north * 1e3, east * 1e3, HULL_HEIGHT_MM), abs=1e-3)
        assert rotation.matrix == pytest.approx(rotation_matrix(yaw, 0.1, -0.2), abs=1e-6)
        _, euler = p.get_6d_euler()
        roll, pitch, heading = euler[1][1]
        assert (roll, pitch, heading) == pytest.approx(
            tuple(math.degrees(a) for a in (-0.2, 0.1, yaw)), abs=1e-4)
        assert bodies[0][0].x == pytest.approx(0.0)
        assert bodies[2][0].x == pytest.approx(2000.0)


def test_frequency_divides_the_camera_rate(server: QtmTestServer) -> None:
    _, packets = asyncio.run(_session(server.port, ["6d"], frames="frequency:25"))
    numbers = [p.framenumber for p in packets]
    assert len(numbers) >= 3
    assert all(n % 4 == 0 for n in numbers)
    assert all(b - a == 4 for a, b in itertools.pairwise(numbers))


def test_bad_commands_are_errors_to_qtm_rt(server: QtmTestServer) -> None:
    async def bad() -> None:
        conn = await qtm_rt.connect("127.0.0.1", port=server.port, version="1.25", timeout=2)
        assert conn is not None
        try:
            with pytest.raises(qtm_rt.QRTCommandException, match="Parse error"):
                await conn.get_parameters(["3d"])
        finally:
            conn.disconnect()

    asyncio.run(bad())


def test_an_unknown_version_is_refused(server: QtmTestServer) -> None:
    # Raw socket: qtm-rt's connect() returns None here but leaves its transport open.
    with socket.create_connection(("127.0.0.1", server.port), timeout=2) as sock:
        greeting = _read_packet(sock)
        sock.sendall(HEADER.pack(HEADER.size + 12, TYPE_COMMAND) + b"version 0.9\0")
        answer = _read_packet(sock)
    assert greeting == (TYPE_COMMAND, b"QTM RT Interface connected\0")
    assert answer == (TYPE_ERROR, b"Version NOT supported\0")


def _read_packet(sock: socket.socket) -> tuple[int, bytes]:
    size, kind = HEADER.unpack(sock.recv(HEADER.size, socket.MSG_WAITALL))
    return kind, sock.recv(size - HEADER.size, socket.MSG_WAITALL)


def test_data_packet_parses_as_qtm_rt_packet() -> None:
    raw = data_packet(123_456_789, 42, ["6d"], [(1.0, 2.0, 3.0, rotation_matrix(0.25)), None],
                      drop_rate=7)
    assert int.from_bytes(raw[:4], "little") == len(raw)
    parsed = QRTPacket(raw[8:])
    assert (parsed.timestamp, parsed.framenumber) == (123_456_789, 42)
    info, bodies = parsed.get_6d()
    assert (info.body_count, info.drop_rate) == (2, 7)
    assert tuple(bodies[0][0]) == (1.0, 2.0, 3.0)
    assert all(math.isnan(v) for v in bodies[1][1].matrix)
