"""The messages the app's workers post to it (dataclasses, as Textual allows)."""

from __future__ import annotations

from array import array
from dataclasses import dataclass

from textual.message import Message

from mavscope.browse.index import FrameIndex
from mavscope.browse.rows import Progress
from mavscope.filter import DisplayFilter


@dataclass
class IndexProgress(Message):
    """The index worker got further (`index` tells which build: a key may have started another)."""

    index: FrameIndex
    progress: Progress


@dataclass
class FilterProgress(Message):
    """The filter worker has looked at `done` of `total` rows; `rows` holds the matches so far."""

    flt: DisplayFilter
    rows: array
    done: int
    total: int
    finished: bool


@dataclass
class Rejudged(Message):
    """Live capture: the capture thread judged the `count` frames `index` held again with new keys."""

    index: FrameIndex
    count: int
