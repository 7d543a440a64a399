"""The field view's web server: the page's files over HTTP and its frames over a websocket, one port.

``ViewServer`` runs the ``websockets`` library's asyncio server in a thread of its own. ``GET /``
and the page's files (share/erforce_sim/web) are plain HTTP; ``/ws`` is the websocket. Frames go
out with ``publish(frame)`` from any thread: a text is encoded once, and the frame queued for every
client, each in a bounded queue that drops its oldest frame when full, so a slow client loses
frames and never slows the caller; a frame given as bytes goes out as a binary message. A client
sends JSON requests (``{"replay": t}`` and the like);
``on_request(request) -> reply`` answers them in the server's thread, and a reply that is a dict
goes back to that client only. Bad input gets an error and never ends the server: an unknown
path a 404, a request that is not JSON an ``{"error": ...}`` message, a malformed or oversized
websocket frame the close code the protocol prescribes (1002, 1009), a client beyond
``max_clients`` a 503.

With ``on_tick`` the server also calls that function every ``tick_period_s`` in its own thread (a
frame it publishes there goes to the clients in the same wake-up): one thread that wakes once per
frame to take, build and send it.
"""

from __future__ import annotations

import asyncio
import http
import json
import logging
import mimetypes
import threading
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

from websockets.asyncio.server import ServerConnection, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

WEBSOCKET_PATH = "/ws"
MAX_REQUEST_BYTES = 4096  # a request is a few dozen bytes of JSON


class _Client:
    def __init__(self, connection: ServerConnection, depth: int) -> None:
        self.connection = connection
        self.queue: deque[tuple[bytes, bool]] = deque(maxlen=depth)  # frames: (bytes, whether UTF-8 text)
        self.ready = asyncio.Event()
        self.dropped = 0


class ViewServer:
    """See the module docstring. ``port`` 0 picks a free port (``port`` tells which once started)."""

    def __init__(self, static_dir: Path, host: str = "127.0.0.1", port: int = 0, max_clients: int = 32,
                 client_queue_depth: int = 4, on_request: Callable[[dict], dict | None] | None = None,
                 logger: logging.Logger | None = None, on_tick: Callable[[], None] | None = None,
                 tick_period_s: float = 1.0 / 30.0) -> None:
        self.static_dir = Path(static_dir).resolve()
        if not (self.static_dir / "index.html").is_file():
            raise FileNotFoundError(f"{self.static_dir}: no index.html (the page's files)")
        self.host = host
        self.port = port
        self.max_clients = max_clients
        self.client_queue_depth = client_queue_depth
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
        self._clients: set[_Client] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._thread_id: int | None = None
        self._stop: asyncio.Event | None = None
        self._started = threading.Event()
        self._error: BaseException | None = None
        self._last_frame: tuple[bytes, bool] | None = None  # the newest frame, for a page that connects now
        self.frames_dropped = 0
        self.requests_refused = 0

    # ------------------------------------------------------------------ lifecycle
    def start(self, timeout_s: float = 10.0) -> None:
        self._thread = threading.Thread(target=self._run, name="field_view_server", daemon=True)
        self._thread.start()
        if not self._started.wait(timeout_s):
            raise RuntimeError("the view server did not start")
        if self._error is not None:
            raise OSError(f"cannot serve on {self.host}:{self.port}: {self._error}") from self._error

    def stop(self) -> None:
        if self._loop is not None and self._stop is not None and self._thread is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
            self._thread.join(timeout=5.0)

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    @property
    def client_count(self) -> int:
        return len(self._clients)

    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as exc:  # reported to start()
            self._error = exc
            self._started.set()

    async def _main(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._thread_id = threading.get_ident()
        self._stop = asyncio.Event()
        async with serve(self._handle, self.host, self.port, process_request=self._http,
                         max_size=MAX_REQUEST_BYTES, max_queue=4, logger=self.log,
                         # a frame is a few kB 30 times a second, mostly to a page on this machine:
                         # deflating it per page cost more CPU than the rest of sending it
                         compression=None) as server:
            self.port = server.sockets[0].getsockname()[1]
            self._started.set()
            ticker = None if self.on_tick is None else asyncio.create_task(self._tick_loop())
            await self._stop.wait()
            if ticker is not None:
                ticker.cancel()

    async def _tick_loop(self) -> None:
        loop = asyncio.get_running_loop()
        due = loop.time()
        while True:
            due += self.tick_period_s
            if due < loop.time():  # late (a starved thread): the next tick one period from now
                due = loop.time() + self.tick_period_s
            await asyncio.sleep(due - loop.time())
            try:
                self.on_tick()
            except Exception:  # a fault of one tick: logged, and the next one comes
                self.tick_failures += 1
                self.log.error("the tick failed", exc_info=True)

    # -------------------------------------------------------------------- output
    def publish(self, frame: str | bytes) -> None:
        """Queue ``frame`` for every client (thread-safe; never blocks): text (encoded once for them all)
        or bytes (a binary message)."""
        item = self._last_frame = (frame.encode(), True) if isinstance(frame, str) else (bytes(frame), False)
        loop = self._loop
        if loop is None or not self._clients:
            return
        if threading.get_ident() == self._thread_id:  # on_tick: no wake-up of this thread needed
            self._fan_out(item)
            return
        try:
            loop.call_soon_threadsafe(self._fan_out, item)
        except RuntimeError:  # the loop closed meanwhile
            pass

    def _fan_out(self, item: tuple[bytes, bool]) -> None:
        for client in self._clients:
            if len(client.queue) == client.queue.maxlen:
                client.dropped += 1
                self.frames_dropped += 1
            client.queue.append(item)
            client.ready.set()

    # ------------------------------------------------------------------- requests
    def _http(self, connection: ServerConnection, request: Request) -> Response | None:
        path = request.path.split("?", 1)[0]
        if path == WEBSOCKET_PATH:
            if len(self._clients) >= self.max_clients:
                self.requests_refused += 1
                return connection.respond(http.HTTPStatus.SERVICE_UNAVAILABLE,
                                          f"at most {self.max_clients} clients\n")
            if "upgrade" not in request.headers.get("Connection", "").lower():
                return connection.respond(http.HTTPStatus.UPGRADE_REQUIRED, "a websocket endpoint\n")
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

    async def _handle(self, connection: ServerConnection) -> None:
        client = _Client(connection, self.client_queue_depth)
        self._clients.add(client)
        if self._last_frame is not None:
            client.queue.append(self._last_frame)
            client.ready.set()
        sender = asyncio.create_task(self._send(client))
        try:
            async for message in connection:
                reply = self._answer(message)
                if reply is not None:
                    await connection.send(json.dumps(reply, allow_nan=False))
        except ConnectionClosed:
            pass
        finally:
            self._clients.discard(client)
            sender.cancel()

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

    async def _send(self, client: _Client) -> None:
        try:
            while True:
                await client.ready.wait()
                client.ready.clear()
                while client.queue:
                    data, text = client.queue.popleft()
                    await client.connection.send(data, text=text)
        except ConnectionClosed:
            pass


# (a frame is a tree of fresh dicts and lists: no cycle to look for)
_FRAME_ENCODER = json.JSONEncoder(separators=(",", ":"), allow_nan=False, check_circular=False)


def frame_text(frame: dict[str, Any]) -> str:
    """A frame as the page reads it (compact JSON; a non-finite number is a bug, so it raises)."""
    return _FRAME_ENCODER.encode({"frame": frame})
