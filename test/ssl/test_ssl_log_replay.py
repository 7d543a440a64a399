"""ssl_log_replay: pacing from the receive times (speed, gaps, clock jumps) on a fake clock, and a real
replay over loopback multicast that delivers every vision and referee payload unchanged and in order."""

import socket
import subprocess
import sys

import pytest

from erforce_interfaces.ssl.ssl_log import LogRecord, LogWriter, MessageType
from erforce_interfaces.ssl.ssl_log_replay import replay

S = 1_000_000_000


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, dt: float) -> None:
        self.sleeps.append(dt)
        self.now += dt


def test_replay_paces_by_receive_time_shortens_gaps_and_skips_other_types():
    records = [LogRecord(10 * S, 4, b"a"), LogRecord(10 * S + S // 2, 3, b"r"), LogRecord(11 * S, 6, b"i"),
               LogRecord(11 * S, 4, b"b"), LogRecord(30 * S, 4, b"c"),  # a 19 s pause: shortened to 2 s
               LogRecord(29 * S, 4, b"d")]  # the log's clock jumped back: sent at once
    clock, sent = FakeClock(), []
    stats = replay(records, lambda kind, data: sent.append((clock.now, kind, data)), speed=2.0, max_gap_s=2.0,
                   clock=clock, sleep=clock.sleep)
    assert [(t - 100.0, k, d) for t, k, d in sent] == [
        (0.0, 4, b"a"), (0.25, 3, b"r"), (0.5, 4, b"b"), (1.5, 4, b"c"), (1.5, 4, b"d")]
    assert stats.sent == {4: 4, 3: 1} and stats.skipped == {6: 1}
    assert stats.log_span_s == pytest.approx(3.0) and stats.speedup == pytest.approx(2.0)


def test_replay_flat_out_never_sleeps():
    clock = FakeClock()
    replay([LogRecord(k * S, 4, b"x") for k in range(10)], lambda *_: None, speed=0.0, clock=clock,
           sleep=clock.sleep)
    assert clock.sleeps == []


def test_replay_refuses_a_bad_speed():
    with pytest.raises(ValueError, match="speed"):
        replay([], lambda *_: None, speed=float("nan"))


def _group_receiver(group: str) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((group, 0))
    membership = socket.inet_aton(group) + socket.inet_aton("127.0.0.1")  # joined on loopback
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, membership)
    sock.settimeout(5.0)
    return sock


def test_cli_replays_a_gzip_log_over_loopback_multicast(tmp_path):
    vision, referee = _group_receiver("224.5.23.2"), _group_receiver("224.5.23.1")
    path = tmp_path / "game.log.gz"
    payloads = [bytes([k]) * (k + 1) for k in range(50)]
    with LogWriter(path) as log:
        for k, p in enumerate(payloads):
            log.write(k * 10_000_000, MessageType.VISION_2014, p)  # 100 Hz
        log.write(S, MessageType.REFBOX_2013, b"referee")
        log.write(S, MessageType.VISION_TRACKER_2020, b"tracked")
    out = subprocess.run(
        [sys.executable, "-m", "erforce_interfaces.ssl.ssl_log_replay", str(path), "--speed", "5", "--quiet",
         "--vision", f"224.5.23.2:{vision.getsockname()[1]}", "--referee", f"224.5.23.1:{referee.getsockname()[1]}"],
        capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert [vision.recv(4096) for _ in payloads] == payloads
    assert referee.recv(4096) == b"referee"
    assert "VISION_2014 50" in out.stdout and "skipped 1 other" in out.stdout
    vision.close()
    referee.close()


def test_cli_refuses_a_file_that_is_no_log(tmp_path):
    bad = tmp_path / "x.log"
    bad.write_bytes(b"not a log at all")
    out = subprocess.run([sys.executable, "-m", "erforce_interfaces.ssl.ssl_log_replay", str(bad), "--quiet"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 1 and "not an SSL log file" in out.stderr
