"""The field view's web server under good and bad input (loopback only): it answers, refuses with an
error, and keeps serving. No ROS here: erforce_sim.view.view_server alone."""

from __future__ import annotations

import base64
import contextlib
import json
import os
import socket
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

from erforce_sim.view.view_server import (
    DIRECT_WRITE_MAX_BYTES,
    MAX_REQUEST_BYTES,
    ViewServer,
    frame_text,
    websocket_frame_header,
)

WEB = Path(__file__).resolve().parents[2] / "src" / "erforce_sim" / "web"


@pytest.fixture
def server():
    def on_request(request: dict) -> dict:
        if "echo" in request:
            return {"echo": request["echo"]}
        raise ValueError("unknown request")

    s = ViewServer(WEB, port=0, max_clients=32, on_request=on_request)
    s.start()
    yield s
    s.stop()


def ws_url(server: ViewServer) -> str:
    return f"ws://127.0.0.1:{server.port}/ws"


def wait_until(condition, timeout_s: float = 5.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def still_serves(server: ViewServer) -> None:
    with connect(ws_url(server), open_timeout=5) as ws:
        ws.send(json.dumps({"echo": 7}))
        assert next_reply(ws) == {"echo": 7}
        wait_until(lambda: server.client_count >= 1)
        server.publish(frame_text({"t": 1.5}))
        while (message := json.loads(ws.recv(timeout=5))) != {"frame": {"t": 1.5}}:
            assert "frame" in message


def next_reply(ws) -> dict:
    """The next message that is not a frame (a page gets the newest frame when it connects)."""
    while "frame" in (message := json.loads(ws.recv(timeout=5))):
        pass
    return message


def test_a_page_that_connects_gets_the_newest_frame_at_once(server):
    server.publish(frame_text({"t": 0.5}))
    server.publish(frame_text({"t": 0.75}))
    with connect(ws_url(server), open_timeout=5) as ws:
        assert json.loads(ws.recv(timeout=5)) == {"frame": {"t": 0.75}}


def test_a_frame_given_as_bytes_goes_out_as_a_binary_message(server):
    with connect(ws_url(server), open_timeout=5) as ws:
        wait_until(lambda: server.client_count >= 1)
        server.publish(b"EFV1\x00\xff")
        assert ws.recv(timeout=5) == b"EFV1\x00\xff"
        server.publish(frame_text({"t": 3.0}))
        assert json.loads(ws.recv(timeout=5)) == {"frame": {"t": 3.0}}


def test_the_frame_header_written_by_hand_is_rfc_6455s():
    # FIN + opcode (0x82 binary, 0x81 text), then a 7-bit length, or 126 and a 16-bit big-endian length
    assert websocket_frame_header(5, text=False) == b"\x82\x05"
    assert websocket_frame_header(125, text=True) == b"\x81\x7d"
    assert websocket_frame_header(126, text=False) == b"\x82\x7e\x00\x7e"
    assert websocket_frame_header(8192, text=False) == b"\x82\x7e\x20\x00"


@pytest.mark.parametrize("size", [0, 125, 126, DIRECT_WRITE_MAX_BYTES, DIRECT_WRITE_MAX_BYTES + 1, 70000])
def test_frames_of_every_header_length_arrive_whole(server, size):
    # up to DIRECT_WRITE_MAX_BYTES the caller writes the frame itself, beyond it the sender thread
    payload = bytes(k % 251 for k in range(size))
    with connect(ws_url(server), open_timeout=5, max_size=None) as ws:
        wait_until(lambda: server.client_count >= 1)
        server.publish(payload)
        assert ws.recv(timeout=5) == payload
        server.publish(frame_text({"t": 2.0}))
        assert json.loads(ws.recv(timeout=5)) == {"frame": {"t": 2.0}}


def test_on_tick_runs_every_period_in_the_servers_thread_and_a_failing_tick_does_not_stop_it():
    ticks: list[float] = []
    server: ViewServer | None = None

    def on_tick() -> None:
        ticks.append(time.monotonic())
        if len(ticks) == 3:
            raise RuntimeError("a fault of one tick")
        server.publish(frame_text({"t": float(len(ticks))}))

    server = ViewServer(WEB, port=0, on_tick=on_tick, tick_period_s=0.02)
    server.start()
    try:
        with connect(ws_url(server), open_timeout=5) as ws:
            first = json.loads(ws.recv(timeout=5))["frame"]["t"]
            while (t := json.loads(ws.recv(timeout=5))["frame"]["t"]) < first + 5:
                assert t != 3.0
        assert server.tick_failures == 1
        assert len(ticks) >= 6 and 0.01 < (ticks[-1] - ticks[0]) / (len(ticks) - 1) < 0.2
    finally:
        server.stop()
    with pytest.raises(ValueError, match="tick_period_s"):
        ViewServer(WEB, on_tick=on_tick, tick_period_s=0.0)


def test_the_page_and_its_files_are_served_and_unknown_paths_are_404(server):
    with urllib.request.urlopen(server.url, timeout=5) as response:
        assert response.status == 200 and b"field_view.js" in response.read()
        assert response.headers["Content-Type"].startswith("text/html")
    with urllib.request.urlopen(server.url + "field_view.js", timeout=5) as response:
        assert response.read() == (WEB / "field_view.js").read_bytes()
    for bad in ("nope", "../setup.py", "web/index.html", "%2e%2e/setup.py", "ws?x=1"):
        with pytest.raises(urllib.error.HTTPError) as error:
            urllib.request.urlopen(server.url + bad, timeout=5)
        assert error.value.code in (404, 426), bad
    still_serves(server)


def test_bad_requests_get_an_error_message_and_the_connection_stays(server):
    with connect(ws_url(server), open_timeout=5) as ws:
        for bad in ("not json", "[1, 2]", '{"nothing": 1}', b"\x00\x01binary"):
            ws.send(bad)
            assert "error" in json.loads(ws.recv(timeout=5)), bad
        ws.send(json.dumps({"echo": "still here"}))
        assert json.loads(ws.recv(timeout=5)) == {"echo": "still here"}


def test_an_oversized_request_closes_that_connection_with_1009_only(server):
    with connect(ws_url(server), open_timeout=5) as ws:
        ws.send("x" * (MAX_REQUEST_BYTES + 1))
        with pytest.raises(ConnectionClosed) as closed:
            ws.recv(timeout=5)
        assert closed.value.rcvd.code == 1009
    still_serves(server)


def _raw_websocket(server: ViewServer) -> socket.socket:
    """A websocket opened by hand, so that the frames sent on it can be anything."""
    sock = socket.create_connection(("127.0.0.1", server.port), timeout=5)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall((f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                  f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
    reply = b""
    while b"\r\n\r\n" not in reply:
        reply += sock.recv(4096)
    assert reply.startswith(b"HTTP/1.1 101")
    return sock


def _close_code(sock: socket.socket) -> int | None:
    """The code of the close frame the server sends (None when it only dropped the connection)."""
    data = b""
    try:
        while chunk := sock.recv(4096):
            data += chunk
    except (ConnectionResetError, TimeoutError):
        pass
    index = data.find(b"\x88")  # FIN + close opcode, unmasked from a server
    return int.from_bytes(data[index + 2:index + 4], "big") if index >= 0 and len(data) >= index + 4 else None


@pytest.mark.parametrize("frame", [
    b"\x81\x05hello",  # unmasked: a client must mask its frames
    b"\x83\x80\x00\x00\x00\x00",  # reserved opcode 3
    b"\xf1\x80\x00\x00\x00\x00",  # reserved bits set
    b"\x09\xfe\x01\x00" + bytes(4) + bytes(256),  # a control frame longer than 125 bytes
    b"\x81\x82\x00\x00\x00\x00\xc3\x28",  # text that is not UTF-8
])
def test_malformed_websocket_frames_close_that_connection_with_a_protocol_error(server, frame):
    sock = _raw_websocket(server)
    sock.sendall(frame)
    assert _close_code(sock) in (1002, 1007)
    sock.close()
    still_serves(server)


def test_a_hundred_clients_get_served_up_to_the_limit_and_a_503_beyond(server):
    opened, refused = [], 0
    with contextlib.ExitStack() as stack:
        for _ in range(100):
            try:
                opened.append(stack.enter_context(connect(ws_url(server), open_timeout=5)))
            except InvalidStatus as exc:
                assert exc.response.status_code == 503
                refused += 1
        assert len(opened) == 32 and refused == 68
        wait_until(lambda: server.client_count == 32)
        server.publish(frame_text({"t": 2.0}))
        for ws in opened:
            assert json.loads(ws.recv(timeout=5)) == {"frame": {"t": 2.0}}
    wait_until(lambda: server.client_count == 0)
    still_serves(server)


def test_a_client_that_never_reads_loses_frames_and_slows_nobody(server):
    slow = _raw_websocket(server)  # never reads: its socket buffers fill, then its pending frames are replaced
    slow.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    with connect(ws_url(server), open_timeout=5) as fast:
        wait_until(lambda: server.client_count == 2)
        big = frame_text({"t": 0.0, "padding": "x" * 100_000})
        start = time.perf_counter()
        for _ in range(300):
            server.publish(big)
        publish_s = time.perf_counter() - start
        server.publish(frame_text({"t": 9.0}))
        # the reading client gets the newest frame; the slow one has dropped many
        deadline = time.monotonic() + 10.0
        while json.loads(fast.recv(timeout=10))["frame"]["t"] != 9.0:
            assert time.monotonic() < deadline
        wait_until(lambda: server.frames_dropped > 100)
    assert publish_s < 0.5  # 300 publishes: left to the clients' senders, never waiting for a client
    slow.close()
    still_serves(server)


def test_stop_ends_within_the_close_timeout_while_a_page_does_not_read():
    server = ViewServer(WEB, port=0)
    server.start()
    stuck = _raw_websocket(server)  # never reads: a write to it blocks in its sender thread
    stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    wait_until(lambda: server.client_count == 1)
    big = frame_text({"t": 0.0, "padding": "x" * 100_000})
    for _ in range(20):
        server.publish(big)
    start = time.monotonic()
    server.stop()
    assert time.monotonic() - start < 3.0  # close_timeout 1 s, not websockets' default 10 s
    stuck.close()
