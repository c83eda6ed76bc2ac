"""Reading MCAP records from a file that may be unfinished, truncated or damaged.

A finished file is read through its index (summary section): each chunk is read on its own, so
a damaged chunk loses only its own messages. A file without a usable index is read by streaming
from the start, stopping at the first record that cannot be read.
"""

from __future__ import annotations

import io
import struct
import zlib
from typing import TYPE_CHECKING

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.stream_reader import breakup_chunk

from armstereo.recording.collect import Collector, describe

if TYPE_CHECKING:
    from armstereo.recording.contents import RecordingContents

MAGIC = b"\x89MCAP0\r\n"
RECORD_HEADER = 9  # opcode (1) + length (8)
FOOTER_RECORD = RECORD_HEADER + 20
MAX_CHUNK_BYTES = 1 << 30  # larger "uncompressed sizes" are taken as damage, not allocated

_PARSERS = {
    Opcode.HEADER: Header.read, Opcode.FOOTER: Footer.read, Opcode.SCHEMA: Schema.read,
    Opcode.CHANNEL: Channel.read, Opcode.CHUNK: Chunk.read, Opcode.MESSAGE_INDEX:
    MessageIndex.read, Opcode.CHUNK_INDEX: ChunkIndex.read, Opcode.METADATA: Metadata.read,
    Opcode.METADATA_INDEX: MetadataIndex.read, Opcode.STATISTICS: Statistics.read,
    Opcode.SUMMARY_OFFSET: SummaryOffset.read, Opcode.DATA_END: DataEnd.read,
}


class _BadRecord(Exception):
    """A record could not be read; the message says where and why."""



def _read_record(f, offset: int, end: int) -> tuple[int, bytes]:
    """Opcode and body of the record at ``offset``; it must end by byte ``end``."""
    f.seek(offset)
    head = f.read(RECORD_HEADER)
    if len(head) < RECORD_HEADER:
        raise _BadRecord(f"the file ends inside a record header at byte {offset}")
    opcode, length = struct.unpack("<BQ", head)
    room = end - offset - RECORD_HEADER
    if length > room:
        raise _BadRecord(f"record at byte {offset} (opcode 0x{opcode:02x}) claims {length} "
                         f"bytes but only {room} remain")
    return opcode, f.read(length)


def _parse(opcode: int, body: bytes):
    """The mcap record object for a record body (None for types we skip)."""
    stream = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.MESSAGE:
        return Message.read(stream, len(body))
    parser = _PARSERS.get(opcode)
    return parser(stream) if parser else None


def _chunk_records(chunk: Chunk) -> list:
    if chunk.compression not in ("", "zstd", "lz4"):
        raise _BadRecord(f"unsupported chunk compression {chunk.compression!r}")
    if chunk.uncompressed_size > MAX_CHUNK_BYTES:
        raise _BadRecord(f"chunk claims {chunk.uncompressed_size} uncompressed bytes "
                         f"(limit {MAX_CHUNK_BYTES})")
    return breakup_chunk(chunk, validate_crc=True)


def _read_one(f, offset: int, end: int) -> tuple[object, list, int]:
    """Record at ``offset``: (record, records to collect, offset after it).

    Any failure, whatever the decoder raised, becomes :class:`_BadRecord`.
    """
    try:
        opcode, body = _read_record(f, offset, end)
        record = _parse(opcode, body)
        inner = _chunk_records(record) if isinstance(record, Chunk) else [record]
    except _BadRecord:
        raise
    except Exception as err:  # hostile bytes can make mcap/zstd/lz4 raise almost anything
        raise _BadRecord(f"record at byte {offset} is damaged ({describe(err)})") from None
    return record, [r for r in inner if r is not None], offset + RECORD_HEADER + len(body)




def scan(f, size: int, collector: Collector, rec: RecordingContents) -> None:
    """Feed every readable record to ``collector``, by index if possible, else by streaming."""
    try:
        summary = _read_summary(f, size)
    except _BadRecord as err:
        rec._warn(f"the index (summary section) is damaged ({err}); read by streaming")
        summary = None
    rec.indexed = summary is not None
    if summary is None:
        rec._warn("no index (summary section): the recording was not finished cleanly; "
                  "read by streaming")
    elif any(isinstance(r, ChunkIndex) for r in summary):
        _scan_indexed(f, size, summary, collector, rec)
        return
    _scan_stream(f, size, collector, rec)  # also for unchunked files, whose index has no chunks


def _read_summary(f, size: int) -> list | None:
    """Summary-section records, or None if the file has no summary (raises _BadRecord)."""
    if size < 2 * len(MAGIC) + FOOTER_RECORD:
        return None
    f.seek(size - len(MAGIC))
    if f.read(len(MAGIC)) != MAGIC:
        return None  # unfinished or cut short
    footer_at = size - len(MAGIC) - FOOTER_RECORD
    footer, _, _ = _read_one(f, footer_at, size - len(MAGIC))
    if not isinstance(footer, Footer):
        raise _BadRecord("the closing magic is not preceded by a footer")
    start = footer.summary_start
    if start == 0:
        return None
    if not len(MAGIC) < start <= footer_at:
        raise _BadRecord(f"summary start {start} lies outside the file")
    if footer.summary_crc:
        f.seek(start)
        crc = zlib.crc32(f.read(size - len(MAGIC) - 4 - start))
        if crc != footer.summary_crc:
            raise _BadRecord("summary CRC mismatch")
    records, offset = [], start
    while offset < footer_at:
        record, _, offset = _read_one(f, offset, footer_at)
        records.append(record)
    return records


def _scan_indexed(f, size: int, summary: list, collector: Collector,
                  rec: RecordingContents) -> None:
    data_end = size
    for record in summary:
        if not isinstance(record, (ChunkIndex, MetadataIndex)):
            collector.add(record)
    for index in (r for r in summary if isinstance(r, MetadataIndex)):
        for r in _try_read(f, index.offset, data_end, rec, f"metadata record '{index.name}'"):
            collector.add(r)
    chunks = sorted((r for r in summary if isinstance(r, ChunkIndex)),
                    key=lambda c: c.chunk_start_offset)
    for index in chunks:
        what = (f"chunk at byte {index.chunk_start_offset} ({index.chunk_length} bytes, "
                f"log time {index.message_start_time}..{index.message_end_time} ns)")
        for r in _try_read(f, index.chunk_start_offset, data_end, rec, what):
            collector.add(r)


def _try_read(f, offset: int, end: int, rec: RecordingContents, what: str) -> list:
    try:
        _, records, _ = _read_one(f, offset, end)
    except _BadRecord as err:
        rec._lose(f"{what} could not be read: {err}")
        return []
    return records


def _scan_stream(f, size: int, collector: Collector, rec: RecordingContents) -> None:
    offset = len(MAGIC)
    unknown = 0
    while True:
        if offset >= size:
            rec.truncated = True
            rec._lose(f"the file ends after {offset} bytes without a footer (capture killed or "
                      "still running); everything up to there was read")
            break
        try:
            record, inner, next_offset = _read_one(f, offset, size)
        except _BadRecord as err:
            rec.truncated = True
            rec._lose(f"reading stopped at byte {offset} of {size}: {err}; the last "
                      f"{size - offset} bytes were not read")
            break
        unknown += record is None
        for r in inner:
            collector.add(r)
        offset = next_offset
        if isinstance(record, Footer):
            break
    if unknown:
        rec._warn(f"skipped {unknown} record(s) of unknown type")


