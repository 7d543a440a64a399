"""SSL log files (``SSL_LOG_FILE``): the league's format for recorded games, plain or gzip.

Layout (all integers big-endian): the 12 ASCII bytes ``SSL_LOG_FILE``, an int32 format version
(1), then records of int64 receive time [ns since the Unix epoch], int32 message type, int32
payload size, payload. Message types are ``MessageType``; the payload of ``VISION_2014`` is an
``SSL_WrapperPacket``, of ``REFBOX_2013`` a ``Referee`` message. A log may end with an index record
(``INDEX_2021``) and its 8-byte offset; the reader skips the index and stops at a truncated tail.

No rclpy here (used by ``ssl_log_replay``, ``ball_fit`` and the plant's log writer).
"""

from __future__ import annotations

import enum
import gzip
import io
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

HEADER = b"SSL_LOG_FILE"
FORMAT_VERSION = 1
GZIP_MAGIC = b"\x1f\x8b"
MAX_RECORD_BYTES = 64 * 1024 * 1024  # a vision frame is < 64 KiB; anything near this is a broken size field

_VERSION = struct.Struct(">i")
_RECORD = struct.Struct(">qii")


class MessageType(enum.IntEnum):
    BLANK = 0
    UNKNOWN = 1
    VISION_2010 = 2
    REFBOX_2013 = 3
    VISION_2014 = 4
    VISION_TRACKER_2020 = 5
    INDEX_2021 = 6


class LogFormatError(ValueError):
    """Not an SSL log file, or a record that cannot be one (with the byte offset)."""


@dataclass(frozen=True)
class LogRecord:
    receive_time_ns: int
    message_type: int  # a MessageType value, or another int a newer writer used
    payload: bytes


def _open(path: str | Path) -> tuple[BinaryIO, BinaryIO]:
    """(the stream to read, the file under it)"""
    raw = open(path, "rb")  # handed to the reader, closed by it
    magic = raw.read(2)
    raw.seek(0)
    if magic == GZIP_MAGIC:
        return gzip.GzipFile(fileobj=raw, mode="rb"), raw
    return raw, raw


class LogReader:
    """Iterates the records of a log file (or a binary stream). After the iteration,
    ``truncated_bytes`` says how many bytes at the end did not form a whole record, and ``skipped``
    counts index records left out."""

    def __init__(self, source: str | Path | BinaryIO) -> None:
        self._owns = isinstance(source, str | Path)
        self._stream, self._raw = _open(source) if self._owns else (source, source)
        self.truncated_bytes = 0
        self.skipped = 0
        self.version = self._read_header()

    def _read_header(self) -> int:
        head = self._stream.read(len(HEADER) + _VERSION.size)
        if head[: len(HEADER)] != HEADER:
            raise LogFormatError(f"not an SSL log file: starts with {head[:12]!r}, expected {HEADER!r}")
        if len(head) < len(HEADER) + _VERSION.size:
            raise LogFormatError("SSL log file ends inside its header")
        (version,) = _VERSION.unpack_from(head, len(HEADER))
        if version != FORMAT_VERSION:
            raise LogFormatError(f"SSL log format version {version} is not supported (only {FORMAT_VERSION})")
        return version

    def position(self) -> int:
        """Bytes of the file read so far (compressed bytes for a gzip file), for progress bars."""
        try:
            return self._raw.tell()
        except (OSError, ValueError):  # closed, or a stream without tell
            return 0

    def __iter__(self) -> Iterator[LogRecord]:
        read = self._stream.read
        offset = len(HEADER) + _VERSION.size
        try:
            while True:
                head = read(_RECORD.size)
                if len(head) < _RECORD.size:
                    self.truncated_bytes = len(head)
                    return
                t_ns, msg_type, size = _RECORD.unpack(head)
                if not 0 <= size <= MAX_RECORD_BYTES:
                    raise LogFormatError(f"record at byte {offset}: payload size {size} is not plausible")
                payload = read(size)
                if len(payload) < size:
                    self.truncated_bytes = _RECORD.size + len(payload)
                    return
                offset += _RECORD.size + size
                if msg_type == MessageType.INDEX_2021:
                    self.skipped += 1
                    continue
                yield LogRecord(t_ns, msg_type, payload)
        except (EOFError, gzip.BadGzipFile, OSError) as exc:  # a cut or corrupt gzip stream
            raise LogFormatError(f"record at byte {offset}: {exc}") from None
        finally:
            if self._owns:
                self._stream.close()
                self._raw.close()


def read_log(source: str | Path | BinaryIO | bytes) -> list[LogRecord]:
    """All records of a log (a path, a stream, or the file's bytes)."""
    if isinstance(source, bytes | bytearray):
        data = bytes(source)
        source = gzip.GzipFile(fileobj=io.BytesIO(data)) if data[:2] == GZIP_MAGIC else io.BytesIO(data)
    return list(LogReader(source))


class LogWriter:
    """Writes an SSL log file; gzip-compressed when the name ends in ``.gz``. Use as a context manager."""

    def __init__(self, path: str | Path, compress: bool | None = None) -> None:
        path = Path(path)
        compress = path.suffix == ".gz" if compress is None else compress
        # compresslevel 1: a 10-minute log in seconds, at about the size of level 9 for these payloads
        self._stream: BinaryIO = gzip.open(path, "wb", compresslevel=1) if compress else open(path, "wb")
        self._stream.write(HEADER + _VERSION.pack(FORMAT_VERSION))
        self.records = 0

    def write(self, receive_time_ns: int, message_type: int, payload: bytes) -> None:
        if len(payload) > MAX_RECORD_BYTES:
            raise ValueError(f"payload of {len(payload)} bytes is larger than a record may be")
        self._stream.write(_RECORD.pack(int(receive_time_ns), int(message_type), len(payload)))
        self._stream.write(payload)
        self.records += 1

    def close(self) -> None:
        self._stream.close()

    def __enter__(self) -> LogWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
