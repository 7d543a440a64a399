"""SSL log files: a hand-written file read back, our writer's bytes equal the hand bytes, gzip, the index
and truncated tails, bad files refused with the reason, and a fuzz of the reader."""

import gzip
import io

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from erforce_interfaces.ssl.ssl_log import LogFormatError, LogReader, LogWriter, MessageType, read_log

# header, version 1; record: t = 1_000_000_007 ns, type 4 (vision 2014), size 3, payload;
# record: t = 2**40 ns, type 3 (referee), size 0
HAND = (b"SSL_LOG_FILE" + b"\x00\x00\x00\x01"
        + bytes.fromhex("000000003b9aca07") + b"\x00\x00\x00\x04" + b"\x00\x00\x00\x03" + b"abc"
        + bytes.fromhex("0000010000000000") + b"\x00\x00\x00\x03" + b"\x00\x00\x00\x00")


def test_message_type_numbers():
    assert [m.value for m in MessageType] == [0, 1, 2, 3, 4, 5, 6]
    assert MessageType.VISION_2014 == 4 and MessageType.REFBOX_2013 == 3 and MessageType.INDEX_2021 == 6


def test_hand_written_file_reads_back():
    records = read_log(HAND)
    assert [(r.receive_time_ns, r.message_type, r.payload) for r in records] == [
        (1_000_000_007, 4, b"abc"), (2**40, 3, b"")]


@pytest.mark.parametrize("name", ["game.log", "game.log.gz"])
def test_writer_produces_the_hand_bytes(tmp_path, name):
    path = tmp_path / name
    with LogWriter(path) as w:
        w.write(1_000_000_007, MessageType.VISION_2014, b"abc")
        w.write(2**40, MessageType.REFBOX_2013, b"")
    raw = path.read_bytes()
    assert (gzip.decompress(raw) if name.endswith(".gz") else raw) == HAND
    assert [r.payload for r in LogReader(path)] == [b"abc", b""]


def test_index_records_are_skipped_and_a_truncated_tail_is_counted():
    index = bytes(8) + b"\x00\x00\x00\x06" + b"\x00\x00\x00\x02" + b"ix"
    reader = LogReader(io.BytesIO(HAND + index + bytes.fromhex("00000000000001f4")))  # the index offset
    assert len(list(reader)) == 2
    assert (reader.skipped, reader.truncated_bytes) == (1, 8)


@pytest.mark.parametrize("data, reason", [
    (b"SSL_LOG_FILX\x00\x00\x00\x01", "not an SSL log file"),
    (b"SSL_LOG_FILE\x00\x00", "inside its header"),
    (b"SSL_LOG_FILE\x00\x00\x00\x02", "version 2"),
    (b"SSL_LOG_FILE\x00\x00\x00\x01" + bytes(8) + b"\x00\x00\x00\x04" + b"\xff\xff\xff\xff", "not plausible"),
])
def test_bad_files_are_refused_with_the_reason(data, reason):
    with pytest.raises(LogFormatError, match=reason):
        read_log(data)


def test_a_cut_gzip_file_is_a_format_error(tmp_path):
    path = tmp_path / "cut.log.gz"
    with LogWriter(path) as w:
        for k in range(2000):
            w.write(k, 4, bytes(range(200)))
    path.write_bytes(path.read_bytes()[:-500])
    with pytest.raises(LogFormatError):
        list(LogReader(path))


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_fuzz_reader_on_garbage_after_a_valid_header(tail):
    try:
        records = read_log(HAND[:16] + tail)
    except LogFormatError:
        return
    assert all(0 <= len(r.payload) <= len(tail) for r in records)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.integers(-2**63, 2**63 - 1), st.integers(0, 6), st.binary(max_size=50)), max_size=20))
def test_fuzz_writer_reader_round_trip(tmp_path_factory, records):
    path = tmp_path_factory.mktemp("log") / "x.log"
    with LogWriter(path) as w:
        for t, kind, payload in records:
            w.write(t, kind, payload)
    back = [(r.receive_time_ns, r.message_type, r.payload) for r in read_log(path)]
    assert back == [r for r in records if r[1] != MessageType.INDEX_2021]
