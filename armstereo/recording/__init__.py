"""MCAP recordings: the contract between live capture and offline reconstruction.

Write with :class:`RecordingWriter`, read with :meth:`Recording.open`; the format (topics,
schemas, frame ids) is defined in :mod:`armstereo.recording.schemas`.
"""

from armstereo.recording.reader import ChannelInfo, Pair, RecordedPointCloud, Recording, View
from armstereo.recording.writer import RecordingWriter

__all__ = ["ChannelInfo", "Pair", "RecordedPointCloud", "Recording", "RecordingWriter", "View"]
