"""Read armstereo recordings, including unfinished, truncated and damaged ones.

A finished file is read through its index (summary section): each chunk is read on its own, so
a damaged chunk loses only its own messages. A file without a usable index (the capture was
killed, the copy was cut short) is read by streaming from the start, stopping at the first record
that cannot be read. Either way :attr:`Recording.lost` says what could not be read and
:attr:`Recording.warnings` lists every problem in one line each. Nothing the file contains can
make the reader raise anything but :class:`RecordingError`.
"""

from __future__ import annotations

import io
import logging
from collections.abc import Iterator
from pathlib import Path

from armstereo.errors import RecordingError
from armstereo.recording import schemas as S
from armstereo.recording.assemble import assemble
from armstereo.recording.collect import Collector
from armstereo.recording.contents import (
    ChannelInfo,
    Pair,
    RecordedPointCloud,
    RecordingContents,
    View,
)
from armstereo.recording.mcap_scan import MAGIC, scan

__all__ = ["ChannelInfo", "Pair", "RecordedPointCloud", "Recording", "View"]

log = logging.getLogger(__name__)


class Recording(RecordingContents):
    """An opened recording: views, pairs, calibration, metadata and what went wrong (the
    fields of :class:`~armstereo.recording.contents.RecordingContents`).

    ``len(rec)``, ``rec[k]`` and iteration give the complete pairs in file order (``rec[k]`` is
    the k-th complete pair; ``Pair.index`` is the number the capture gave it). Access to pairs
    raises :class:`RecordingError` when the file has no camera calibration.
    """

    @classmethod
    def open(cls, path: str | Path) -> Recording:
        """Read ``path``; raises :class:`RecordingError` only if it is not a readable MCAP file."""
        path = Path(path)
        try:
            with open(path, "rb") as f:
                size = f.seek(0, io.SEEK_END)
                f.seek(0)
                if size == 0:
                    raise RecordingError(f"{path} is empty (0 bytes), not an MCAP file")
                if f.read(len(MAGIC)) != MAGIC:
                    raise RecordingError(f"{path} is not an MCAP file (bad magic)")
                rec = cls(path, size)
                collector = Collector()
                scan(f, size, collector, rec)
        except OSError as err:
            raise RecordingError(f"cannot read recording {path}: {err.strerror or err}") from None
        assemble(rec, collector)
        for text in rec.warnings:
            log.debug("%s: %s", path.name, text)
        return rec

    # ---------------------------------------------------------------------------- pair access
    @property
    def pairs(self) -> list[Pair]:
        """The complete pairs; raises :class:`RecordingError` without a camera calibration."""
        if self.calibration is None:
            raise RecordingError(f"{self.path} has no {S.TOPIC_CALIBRATION} message; the "
                                 "pairs need the camera intrinsics")
        return list(self._pairs)

    def require_pairs(self) -> list[Pair]:
        """The complete pairs; raises :class:`RecordingError` if there are none."""
        pairs = self.pairs
        if not pairs:
            raise RecordingError(f"{self.path} has no complete stereo pair ({len(self.views)} "
                                 f"complete view(s), {len(self.pair_events)} pair event(s))")
        return pairs

    def __len__(self) -> int:
        return len(self._pairs)

    def __getitem__(self, k: int) -> Pair:
        pairs = self.pairs
        try:
            return pairs[k]
        except IndexError:
            raise IndexError(f"pair {k} out of range: {self.path} has {len(pairs)} "
                             "complete pair(s)") from None

    def __iter__(self) -> Iterator[Pair]:
        return iter(self.pairs)

    def view(self, index: int) -> View:
        """The complete view numbered ``index``; raises :class:`RecordingError` if absent."""
        for v in self.views:
            if v.index == index:
                return v
        raise RecordingError(f"{self.path} has no complete view {index}")

    @property
    def duration_s(self) -> float | None:
        """Time from the first to the last message read (s), None without messages."""
        if self.start_ns is None or self.end_ns is None:
            return None
        return (self.end_ns - self.start_ns) / 1e9
