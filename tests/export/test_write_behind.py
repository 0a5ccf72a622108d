"""`dataset.write_behind`: the export writes Parquet on a thread of its own while the next batches are made.
Every batch is written, in order; an error on either side stops both and is raised to the caller, and the
batches' generator is closed (its capture file and walker with it)."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from mavscope.export.dataset import WRITE_BEHIND, write_behind


class Boom(Exception):
    pass


def test_every_batch_is_written_in_order_on_another_thread() -> None:
    written: list[tuple[int, str]] = []
    write_behind(iter(range(50)), lambda b: written.append((b, threading.current_thread().name)))  # type: ignore[arg-type]
    assert [b for b, _ in written] == list(range(50))
    assert {name for _, name in written} == {"mavscope-parquet"}


def test_a_write_error_stops_the_batches_and_is_raised() -> None:
    made: list[int] = []
    closed: list[bool] = []

    def batches() -> Iterator[int]:
        try:
            for i in range(1000):
                made.append(i)
                yield i
        finally:
            closed.append(True)

    def write(b: int) -> None:
        if b == 3:
            raise Boom("disk full")

    with pytest.raises(Boom, match="disk full"):
        write_behind(batches(), write)  # type: ignore[arg-type]
    assert closed == [True]
    assert len(made) < 3 + WRITE_BEHIND + 10  # made before the writer's error was seen: a few, not all 1000


def test_an_error_making_the_batches_is_raised_after_what_came_before_is_written() -> None:
    written: list[int] = []

    def batches() -> Iterator[int]:
        yield 1
        yield 2
        raise Boom("capture cut")

    with pytest.raises(Boom, match="capture cut"):
        write_behind(batches(), written.append)  # type: ignore[arg-type]
    assert written == [1, 2]
