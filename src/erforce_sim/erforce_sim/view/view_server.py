"""The field view's web server: the page's files over HTTP and its frames over a websocket, one port.

``ViewServer`` runs the ``websockets`` library's threaded server (``websockets.sync``): a thread accepts,
and each connection has a thread of its own that reads its requests. ``GET /`` and the page's files
(share/erforce_sim/web) are plain HTTP; ``/ws`` is the websocket. Frames go out with ``publish(frame)``
from any thread: a text is encoded once, and a frame given as bytes goes out as a binary message. A
frame that fits in a client's empty socket buffer is written at once by the caller (the usual case:
no thread wakes for it); otherwise it waits as that client's pending frame, which its own sender thread
writes, and a newer frame replaces it (counted in ``frames_dropped``), so a slow client loses frames
and never slows the caller. A client sends JSON requests (``{"replay": t}`` and the like);
``on_request(request) -> reply`` answers them in that client's thread, and a reply that is a dict
goes back to that client only. Bad input gets an error and never ends the server: an unknown
path a 404, a request that is not JSON an ``{"error": ...}`` message, a malformed or oversized
websocket frame the close code the protocol prescribes (1002, 1009), a client beyond
``max_clients`` a 503.

With ``on_tick`` the server also calls that function every ``tick_period_s`` in a thread of its own
(a frame it publishes there is written in the same wake-up): one thread that wakes once per frame to
take, build and send it.
"""

from __future__ import annotations

import contextlib
import fcntl
import http
import json
import logging
import mimetypes
import socket
import struct
import termios
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response
from websockets.protocol import State
from websockets.sync.server import ServerConnection, serve

from erforce_interfaces.runtime.param_schema import schema_defaults

_VIEW = schema_defaults("erforce_sim", "field_view")  # the field view node's defaults

WEBSOCKET_PATH = "/ws"
MAX_REQUEST_BYTES = 4096  # a request is a few dozen bytes of JSON
#: A frame up to this size goes out from the caller's thread when the client's socket has nothing
#: unsent: it fits in the socket's smallest send buffer (tcp_wmem's default 16 kB, with the kernel's
#: per-buffer overhead), so the write cannot block.
DIRECT_WRITE_MAX_BYTES = 8192


_SHORT_HEADER = struct.Struct("!BB")
_MEDIUM_HEADER = struct.Struct("!BBH")


def websocket_frame_header(size: int, text: bool) -> bytes:
    """The header of one final, unmasked websocket frame of ``size`` bytes (RFC 6455 5.2), up to 65535."""
    opcode = 0x81 if text else 0x82  # FIN and text (1) or binary (2)
    if size < 126:
        return _SHORT_HEADER.pack(opcode, size)
    if size < 65536:
        return _MEDIUM_HEADER.pack(opcode, 126, size)
    raise ValueError(f"a frame of {size} bytes: longer than this header covers")


class _Client:
    """One page: its connection, and the frame waiting for its sender thread (see the module docstring)."""

    def __init__(self, connection: ServerConnection, server: ViewServer) -> None:
        self.connection = connection
        self.server = server
        self.socket: socket.socket = connection.socket
        self.lock = threading.Condition()
        self.pending: tuple[bytes, bool] | None = None  # (bytes, whether UTF-8 text)
        self.busy = False  # a thread is writing to the connection
        self.closed = False
        self.dropped = 0
        self.replies_waiting = 0  # send_now callers waiting for the connection

    def offer(self, item: tuple[bytes, bool]) -> None:
        """Write ``item`` now if that cannot block, else leave it to the sender thread."""
        with self.lock:
            if self.closed:
                return
            direct = not self.busy and self.pending is None and self._room_for(len(item[0]))
            if direct:
                self.busy = True
            else:
                if self.pending is not None:
                    self.dropped += 1
                    self.server.frames_dropped += 1
                self.pending = item
                self.lock.notify()
                return
        self._write_framed(item)

    def _room_for(self, size: int) -> bool:
        if size > DIRECT_WRITE_MAX_BYTES:
            return False
        try:
            return int.from_bytes(fcntl.ioctl(self.socket, termios.TIOCOUTQ, b"\0\0\0\0"), "little") == 0
        except (OSError, ValueError):  # closed meanwhile (ValueError: its descriptor is -1 now)
            return False

    def _write(self, item: tuple[bytes, bool]) -> None:
        """Write ``item`` while this thread holds ``busy``; release it after."""
        try:
            self.connection.send(item[0], text=item[1])
        except (ConnectionClosed, OSError):
            self.close()
        finally:
            self._release()

    def _release(self) -> None:
        """Give up ``busy``; wake the sender thread only for a frame or reply it has to write (not after
        every direct write)."""
        with self.lock:
            self.busy = False
            if self.pending is not None or self.replies_waiting:
                self.lock.notify_all()

    def _write_framed(self, item: tuple[bytes, bool]) -> None:
        """As ``_write``, for a frame that fits in the empty socket buffer: one write of the websocket frame
        built here (an unmasked single frame, as a server sends), under the connection's own lock, instead
        of the library's send path, whose Python per frame cost more than the rest of the send."""
        data, text = item
        connection = self.connection
        try:
            with connection.protocol_mutex:  # (its writers drain what they queue under it: nothing is queued)
                if connection.protocol.state is not State.OPEN:
                    raise ConnectionClosed(None, None)
                connection.socket.sendall(websocket_frame_header(len(data), text) + data)
        except (ConnectionClosed, OSError):
            self.close()
        finally:
            self._release()

    def send_now(self, item: tuple[bytes, bool]) -> None:
        """Write ``item`` (a reply) after what is being written, never dropped; blocks only this client's thread."""
        with self.lock:
            self.replies_waiting += 1
            try:
                while self.busy and not self.closed:
                    self.lock.wait()
            finally:
                self.replies_waiting -= 1
            if self.closed:
                return
            self.busy = True
        self._write(item)

    def run_sender(self) -> None:
        """The sender thread: writes pending frames, blocking as long as the client takes to read them."""
        while True:
            with self.lock:
                while not self.closed and (self.pending is None or self.busy):
                    self.lock.wait()
                if self.closed:
                    return
                item, self.pending, self.busy = self.pending, None, True
            self._write(item)

    def close(self) -> None:
        with self.lock:
            self.closed = True
            self.lock.notify_all()


class ViewServer:
    """See the module docstring. ``port`` 0 picks a free port (``port`` tells which once started)."""

    def __init__(self, static_dir: Path, host: str = _VIEW["host"], port: int = 0,
                 max_clients: int = _VIEW["max_clients"],
                 on_request: Callable[[dict], dict | None] | None = None,
                 logger: logging.Logger | None = None, on_tick: Callable[[], None] | None = None,
                 tick_period_s: float = 1.0 / 30.0) -> None:
        self.static_dir = Path(static_dir).resolve()
        if not (self.static_dir / "index.html").is_file():
            raise FileNotFoundError(f"{self.static_dir}: no index.html (the page's files)")
        self.host = host
        self.port = port
        self.max_clients = max_clients
        self.on_request = on_request
        if on_tick is not None and not tick_period_s > 0.0:
            raise ValueError(f"tick_period_s must be > 0, got {tick_period_s!r}")
        self.on_tick = on_tick
        self.tick_period_s = tick_period_s
        self.tick_failures = 0
        self.log = logger or logging.getLogger("field_view")
        self._files = {f"/{p.relative_to(self.static_dir).as_posix()}": p
                       for p in self.static_dir.rglob("*") if p.is_file()}
        self._files["/"] = self.static_dir / "index.html"
        self._clients_lock = threading.Lock()
        self._clients: tuple[_Client, ...] = ()  # replaced, never changed in place: publish reads it unlocked
        self._admitted: set[ServerConnection] = set()  # handshakes accepted, clients not yet registered
        self._server = None
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()
        self._last_frame: tuple[bytes, bool] | None = None  # the newest frame, for a page that connects now
        self.frames_dropped = 0
        self.requests_refused = 0

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> None:
        try:
            self._server = serve(self._handle, self.host, self.port, process_request=self._http,
                                 max_size=MAX_REQUEST_BYTES, max_queue=4, logger=self.log,
                                 # a frame is a few kB 30 times a second, mostly to a page on this machine:
                                 # deflating it per page cost more CPU than the rest of sending it
                                 compression=None,
                                 # no keep-alive pings: frames go out 30 times a second, and a write to a
                                 # page that is gone fails; a ping could only hold the connection's lock
                                 ping_interval=None,
                                 # stop() waits this long at most for a page to answer the close
                                 close_timeout=1.0)
        except OSError as exc:
            raise OSError(f"cannot serve on {self.host}:{self.port}: {exc}") from exc
        self.port = self._server.socket.getsockname()[1]
        self._threads = [threading.Thread(target=self._server.serve_forever, name="field_view_server", daemon=True)]
        if self.on_tick is not None:
            self._threads.append(threading.Thread(target=self._tick_loop, name="field_view_tick", daemon=True))
        for thread in self._threads:
            thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._server is not None:
            for client in self._clients:
                client.close()
                if client.busy:  # a write to a page that does not read: end it, or the close waits for it
                    with contextlib.suppress(OSError):
                        client.socket.shutdown(socket.SHUT_RDWR)
            self._server.shutdown()
            self._server = None
        for thread in self._threads:
            thread.join(timeout=5.0)

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    @property
    def client_count(self) -> int:
        return len(self._clients)

    def _tick_loop(self) -> None:
        due = time.monotonic()
        while True:
            due += self.tick_period_s
            now = time.monotonic()
            if due < now:  # late (a starved thread): the next tick one period from now
                due = now + self.tick_period_s
            time.sleep(due - now)  # (an Event's timed wait costs several times more CPU per wake-up)
            if self._stop.is_set():
                return
            try:
                self.on_tick()
            except Exception:  # a fault of one tick: logged, and the next one comes
                self.tick_failures += 1
                self.log.error("the tick failed", exc_info=True)

    # -------------------------------------------------------------------- output
    def publish(self, frame: str | bytes) -> None:
        """Send ``frame`` to every client (thread-safe; never blocks): text (encoded once for them all)
        or bytes (a binary message)."""
        item = self._last_frame = (frame.encode(), True) if isinstance(frame, str) else (bytes(frame), False)
        for client in self._clients:
            client.offer(item)

    # ------------------------------------------------------------------- requests
    def _http(self, connection: ServerConnection, request: Request) -> Response | None:
        path = request.path.split("?", 1)[0]
        if path == WEBSOCKET_PATH:
            if "upgrade" not in request.headers.get("Connection", "").lower():
                return connection.respond(http.HTTPStatus.UPGRADE_REQUIRED, "a websocket endpoint\n")
            # Each connection's thread registers its client only after the handshake: the slot is taken
            # here, under the lock, or clients connecting at once would all pass the count.
            with self._clients_lock:
                self._admitted = {c for c in self._admitted if c.state is not State.CLOSED}  # failed handshakes
                if len(self._clients) + len(self._admitted) >= self.max_clients:
                    self.requests_refused += 1
                    return connection.respond(http.HTTPStatus.SERVICE_UNAVAILABLE,
                                              f"at most {self.max_clients} clients\n")
                self._admitted.add(connection)
            return None
        file = self._files.get(path)
        if file is None:
            self.requests_refused += 1
            return connection.respond(http.HTTPStatus.NOT_FOUND, f"no such page: {path[:100]}\n")
        body = file.read_bytes()
        kind = mimetypes.guess_type(file.name)[0] or "application/octet-stream"
        headers = Headers([
            ("Content-Type", kind + ("; charset=utf-8" if kind.startswith("text/") or kind.endswith("javascript")
                                     else "")),
            ("Content-Length", str(len(body))),
            ("Cache-Control", "no-store"),
            ("Connection", "close"),
        ])
        return Response(http.HTTPStatus.OK, "OK", headers, body)

    def _handle(self, connection: ServerConnection) -> None:
        """One client's thread: its requests, while its sender thread writes what waits."""
        client = _Client(connection, self)
        sender = threading.Thread(target=client.run_sender, name="field_view_sender", daemon=True)
        sender.start()
        with self._clients_lock:
            self._admitted.discard(connection)
            self._clients = (*self._clients, client)
        if self._last_frame is not None:
            client.offer(self._last_frame)
        try:
            for message in connection:
                reply = self._answer(message)
                if reply is not None:
                    client.send_now((json.dumps(reply, allow_nan=False).encode(), True))
        except ConnectionClosed:
            pass
        finally:
            with self._clients_lock:
                self._clients = tuple(c for c in self._clients if c is not client)
            client.close()
            sender.join(timeout=5.0)

    def _answer(self, message: str | bytes) -> dict | None:
        if isinstance(message, bytes):
            return {"error": "requests are JSON text messages"}
        try:
            request = json.loads(message)
        except ValueError as exc:
            return {"error": f"not JSON: {exc}"}
        if not isinstance(request, dict):
            return {"error": "a request is a JSON object"}
        if self.on_request is None:
            return {"error": "this server takes no requests"}
        try:
            return self.on_request(request)
        except (ValueError, TypeError, KeyError) as exc:
            return {"error": f"bad request: {exc}"}


# (a frame is a tree of fresh dicts and lists: no cycle to look for)
_FRAME_ENCODER = json.JSONEncoder(separators=(",", ":"), allow_nan=False, check_circular=False)


def frame_text(frame: dict[str, Any]) -> str:
    """A frame as the page reads it (compact JSON; a non-finite number is a bug, so it raises)."""
    return _FRAME_ENCODER.encode({"frame": frame})
