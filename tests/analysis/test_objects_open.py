"""Which transfer in progress is closed early when too many are open: the one seen least recently (the one
started first among equals), found without scanning all of them for every new transfer."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from mavscope.analysis.objects import Limits
from mavscope.analysis.objects.context import Context
from mavscope.analysis.objects.model import DOWNLOAD, FTP_READ, Transfer
from tests.support.cost import lines_run

# ("start",) | ("see", k): the k-th open transfer (mod their number) is active | ("end", k): it finishes
steps = st.lists(st.one_of(st.just(("start", 0)), st.tuples(st.just("see"), st.integers(0, 50)),
                           st.tuples(st.just("end"), st.integers(0, 50))), max_size=300)


class Run:
    def __init__(self, max_open: int) -> None:
        self.ctx = Context(Limits(max_open=max_open))
        self.closed: list[int] = []

    def start(self) -> Transfer:
        return self.ctx.start(FTP_READ, DOWNLOAD, (1, 1), (255, 190), self.close)

    def close(self, t: Transfer) -> None:
        self.closed.append(t.order)
        self.ctx.finish(t, size=0, gaps=[], end_known=False, complete=False, received=0)


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 6), steps)
def test_the_least_recently_seen_transfer_is_closed(max_open: int, ops: list[tuple[str, int]]) -> None:
    run = Run(max_open)
    expected: list[int] = []
    for op, k in ops:
        run.ctx.tick += 1
        live = [t for t, _ in run.ctx.open.values()]
        if op == "start":
            if len(live) >= max_open:  # the plain rule: min over the open ones by last activity, ties by start
                expected.append(min(live, key=lambda t: (t.last_seen, t.order)).order)
            run.start()
        elif live and op == "see":
            live[k % len(live)].last_seen = run.ctx.tick
        elif live:
            run.ctx.finish(live[k % len(live)], size=0, gaps=[], end_known=False, complete=False, received=0)
        assert run.closed == expected


def test_a_new_transfer_does_not_scan_the_open_ones() -> None:
    def cost(max_open: int) -> int:
        run = Run(max_open)
        for _ in range(max_open):
            run.start()
            run.ctx.tick += 1
        n = lines_run(run.start)  # closes transfer 1 (its record is made: the same work whatever max_open)
        assert len(run.ctx.open) == max_open and run.closed == [1]
        return n

    # the min over the open transfers ran its key once per transfer: 252 lines more with 256 open than 4
    assert cost(256) - cost(4) < 20
