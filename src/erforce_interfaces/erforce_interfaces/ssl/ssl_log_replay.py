"""ssl_log_replay: play the vision and referee records of an SSL log file into the network, as
SSL-Vision and the game controller would send them (UDP multicast), at the recorded pace or faster.

``ssl_vision_bridge`` (and any other SSL tool) picks the packets up as if live: a recorded game drives
the ball predictor. Vision records (``VISION_2014``) go to the vision group (224.5.23.2:10006 by
default, the league's), referee records (``REFBOX_2013``) to 224.5.23.1:10003; other record types
are counted and skipped. ``--speed 2`` plays twice as fast, ``--speed 0`` as fast as possible; gaps
in the log longer than ``--max-gap-s`` are shortened to it (a log paused at half time).

The multicast interface defaults to loopback (127.0.0.1) with TTL 0, so nothing leaves the machine
unless you name a network interface's address and ``--ttl 1``. No rclpy here.
"""

from __future__ import annotations

import argparse
import math
import socket
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from erforce_interfaces.ssl.ssl_log import LogFormatError, LogReader, LogRecord, MessageType
from erforce_interfaces.ssl.ssl_vision import SSL_VISION_GROUP, SSL_VISION_INTERFACE, SSL_VISION_PORT

VISION_GROUP = (SSL_VISION_GROUP, SSL_VISION_PORT)
REFEREE_GROUP = ("224.5.23.1", 10003)


@dataclass
class ReplayStats:
    sent: dict[int, int] = field(default_factory=dict)  # per message type
    skipped: dict[int, int] = field(default_factory=dict)
    send_errors: int = 0
    log_span_s: float = 0.0  # receive time of the last record minus the first, gaps shortened
    wall_s: float = 0.0

    @property
    def speedup(self) -> float:
        return self.log_span_s / self.wall_s if self.wall_s > 0.0 else math.inf


def replay(records: Iterable[LogRecord], send: Callable[[int, bytes], None], speed: float = 1.0,
           max_gap_s: float = 5.0, clock: Callable[[], float] = time.monotonic,
           sleep: Callable[[float], None] = time.sleep, on_record: Callable[[LogRecord], None] | None = None,
           ) -> ReplayStats:
    """Send each record of a type ``send`` takes (vision, referee) when it falls due.

    Record ``k`` is due ``(t_k - t_0) / speed`` after the start (``t`` the receive time, with gaps
    longer than ``max_gap_s`` shortened to it); ``speed`` 0 sends without waiting. A record older than
    its predecessor (clock jumps in the log) is sent at once.
    """
    if not (speed >= 0.0 and math.isfinite(speed)):
        raise ValueError(f"speed must be finite and >= 0, got {speed!r}")
    stats = ReplayStats()
    start_wall = clock()
    log_t = 0.0  # seconds since the first record, gaps shortened
    prev_ns: int | None = None
    for rec in records:
        if rec.message_type not in (MessageType.VISION_2014, MessageType.REFBOX_2013):
            stats.skipped[rec.message_type] = stats.skipped.get(rec.message_type, 0) + 1
            continue
        if prev_ns is not None:
            log_t += min(max(rec.receive_time_ns - prev_ns, 0) * 1e-9, max_gap_s)
        prev_ns = rec.receive_time_ns
        if speed > 0.0:
            wait = start_wall + log_t / speed - clock()
            if wait > 0.0:
                sleep(wait)
        try:
            send(rec.message_type, rec.payload)
            stats.sent[rec.message_type] = stats.sent.get(rec.message_type, 0) + 1
        except OSError:
            stats.send_errors += 1
        if on_record is not None:
            on_record(rec)
    stats.log_span_s = log_t
    stats.wall_s = clock() - start_wall
    return stats


def multicast_sender(interface: str, ttl: int = 0) -> socket.socket:
    """A UDP socket that sends multicast on ``interface`` (an address), looped back to this host;
    TTL 0 keeps the packets on this host."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, ttl)
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(interface))
    return sock


def _address(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    try:
        socket.inet_aton(host)
        return host, int(port)
    except (OSError, ValueError):
        raise argparse.ArgumentTypeError(f"expected ADDRESS:PORT, got {text!r}") from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="ssl_log_replay", description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path, help="SSL log file (plain or .gz)")
    parser.add_argument("--speed", type=float, default=1.0, help="1 = recorded pace, 2 = twice as fast, 0 = flat out")
    parser.add_argument("--vision", type=_address, default=VISION_GROUP, metavar="ADDRESS:PORT",
                        help=f"where vision packets go (default {VISION_GROUP[0]}:{VISION_GROUP[1]})")
    parser.add_argument("--referee", type=_address, default=REFEREE_GROUP, metavar="ADDRESS:PORT",
                        help=f"where referee packets go (default {REFEREE_GROUP[0]}:{REFEREE_GROUP[1]})")
    parser.add_argument("--no-referee", action="store_true", help="send vision only")
    parser.add_argument("--interface", default=SSL_VISION_INTERFACE,
                        help="address of the interface multicast leaves on")
    parser.add_argument("--ttl", type=int, default=0, choices=range(256), metavar="0..255",
                        help="multicast TTL: 0 stays on this host, 1 reaches the local network")
    parser.add_argument("--max-gap-s", type=float, default=5.0, help="shorten longer pauses in the log to this [s]")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if not (args.speed >= 0.0 and math.isfinite(args.speed)):
        parser.error("--speed must be finite and >= 0")
    try:
        sock = multicast_sender(args.interface, args.ttl)
        reader = LogReader(args.log)
    except (OSError, LogFormatError) as exc:
        print(f"ssl_log_replay: {exc}", file=sys.stderr)
        return 1
    targets = {MessageType.VISION_2014: args.vision}
    if not args.no_referee:
        targets[MessageType.REFBOX_2013] = args.referee

    def send(message_type: int, payload: bytes) -> None:
        target = targets.get(message_type)
        if target is not None:
            sock.sendto(payload, target)

    from tqdm import tqdm  # only the command line needs it

    size = args.log.stat().st_size
    with tqdm(total=size, unit="B", unit_scale=True, disable=args.quiet, desc=args.log.name) as bar:
        def progress(_record: LogRecord) -> None:
            done = reader.position()
            if done - bar.n > size / 200:
                bar.update(done - bar.n)

        try:
            stats = replay(reader, send, args.speed, args.max_gap_s, on_record=progress)
        except (LogFormatError, KeyboardInterrupt) as exc:
            print(f"ssl_log_replay: stopped: {exc or 'interrupted'}", file=sys.stderr)
            return 1
        bar.update(size - bar.n)
    sent = ", ".join(f"{MessageType(k).name} {v}" for k, v in sorted(stats.sent.items())) or "nothing"
    print(f"sent {sent} in {stats.wall_s:.1f} s ({stats.speedup:.1f}x the log's {stats.log_span_s:.1f} s); "
          f"skipped {sum(stats.skipped.values())} other records, {stats.send_errors} send errors, "
          f"{reader.truncated_bytes} bytes of a truncated tail")
    return 0


if __name__ == "__main__":
    sys.exit(main())
