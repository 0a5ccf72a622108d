"""The mission reconstruction's indexes against the scans they replace, and what a frame costs it.

Each expectation is the plain scan over every open transfer or event that reconstruct.py ran until stop 23
(`model.same` on both ends, `now - last > timeout`): 200,000 frames of MISSION_COUNTs between 250 x 250
systems took `mission` 88 s in those scans. The whole tracker was also compared with the scanning one on
1,800 random exchanges (timed and untimed; the note of stop 23 says how)."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as apm

from mavscope.analysis.mission.model import OPEN_MAX, Event, Item, Transfer, same
from mavscope.analysis.mission.reconstruct import MissionTracker
from mavscope.analysis.mission.state import Deadlines, narrow, open_events, open_transfers
from mavscope.mavlink.dialect import Dialect
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import open_session
from tests.support.builders import tlog_spaced
from tests.support.cost import lines_run

ADDRS = st.tuples(st.sampled_from([0, 1, 2]), st.sampled_from([0, 1, 190]))  # system or component 0: a broadcast
TYPES = st.sampled_from([0, 1])
OPS = st.lists(st.one_of(
    st.tuples(st.just("add"), TYPES, ADDRS, ADDRS),
    st.tuples(st.just("remove"), st.integers(0, 40)),
    st.tuples(st.just("narrow"), st.integers(0, 40), st.sampled_from([1, 190])),
    st.tuples(st.just("ask"), TYPES, ADDRS, ADDRS),
), max_size=60)


@settings(max_examples=300, deadline=None)
@given(ops=OPS)
def test_the_transfer_index_is_the_scan(ops: list[tuple]) -> None:
    index, live, order = open_transfers(), [], 0
    for op in ops:
        if op[0] == "add":
            order += 1
            t = Transfer(op[2], op[3], op[1], 1, None, order)
            index.add(t)
            live.append(t)
        elif op[0] in ("remove", "narrow") and live:
            t = live[op[1] % len(live)]
            if op[0] == "remove":
                index.remove(t)
                live.remove(t)
            elif t.receiver[1] == 0:  # a receiver narrows from component 0 only
                narrow(index, t, (t.receiver[0], op[2]))
        elif op[0] == "ask":
            _, mtype, a, b = op
            scan = [t for t in live if t.mission_type == mtype and same(t.sender, a) and same(t.receiver, b)]
            assert index.matching(mtype, a, b) == scan
            assert index.latest(mtype, a, b) is (scan[-1] if scan else None)
            assert index.first(mtype, a, b) is (scan[0] if scan else None)
            back = [t for t in live if t.mission_type == mtype and (
                (same(t.sender, a) and same(t.receiver, b)) or (same(t.sender, b) and same(t.receiver, a)))]
            assert index.between(mtype, a, b) == back
        assert list(index) == live and len(index) == len(live)
        assert (index.oldest() if live else None) is (live[0] if live else None)


@settings(max_examples=200, deadline=None)
@given(events=st.lists(st.tuples(TYPES, ADDRS, ADDRS), max_size=30), mtype=TYPES, a=ADDRS, b=ADDRS)
def test_the_event_index_with_an_exact_sender_is_the_scan(events: list[tuple], mtype: int, a: tuple[int, int],
                                                         b: tuple[int, int]) -> None:
    index = open_events()
    made = [Event("clear-all", s, t, m, None, n) for n, (m, s, t) in enumerate(events)]
    for ev in made:
        index.add(ev)
    scan = [ev for ev in made if ev.mission_type == mtype and ev.sender == a and same(ev.target, b)]
    assert index.first(mtype, a, b, exact_sender=True) is (scan[0] if scan else None)


class Obj:
    def __init__(self, last: float | None) -> None:
        self.last = last


@settings(max_examples=300, deadline=None)
@given(steps=st.lists(st.tuples(st.integers(0, 9), st.one_of(st.none(), st.floats(-50, 50)), st.floats(-50, 80),
                                st.booleans()), max_size=50))
def test_deadlines_hand_back_what_a_scan_finds_stale(steps: list[tuple[int, float | None, float, bool]]) -> None:
    """Objects touched at times that may run backwards, some dropped; at each step the objects handed
    back are exactly the followed ones with now - last > timeout, and they are no longer followed."""
    objs = [Obj(None) for _ in range(10)]
    followed: set[int] = set()
    d = Deadlines(10.0)
    for i, last, now, drop in steps:
        o = objs[i]
        if drop:
            followed.discard(i)
        else:
            o.last = last
            followed.add(i)
            d.push(o)
        stale = {j for j in followed if objs[j].last is not None and now - objs[j].last > 10.0}  # type: ignore[operator]
        got = d.due(now, lambda x: objs.index(x) in followed)  # type: ignore[arg-type]
        assert sorted(objs.index(x) for x in got) == sorted(stale)  # type: ignore[arg-type]
        followed -= stale


def test_deadlines_stay_small_when_the_clock_runs_backwards() -> None:
    d, o = Deadlines(10.0), Obj(None)
    for k in range(50_000):  # the same object touched 50,000 times, each time earlier: nothing ever surfaces
        o.last = -float(k)
        d.push(o)
        d.compact(1, lambda: [o])
    assert len(d._heap) <= 4 + 4096 + 1
    assert d.due(20.0, lambda x: True) == [o]


def _frames_of(tmp_path: Path, name: str, raws: list[bytes]) -> list:  # type: ignore[type-arg]
    """`raws` as a tlog (one frame a millisecond), read back through the pipeline."""
    path = tmp_path / name
    path.write_bytes(tlog_spaced(raws, 1_700_000_000_000_000, 1000))
    with open_session(str(path), PipelineOptions()) as s:
        return list(s.frames())


def test_a_frame_costs_the_same_however_many_transfers_are_open(tmp_path: Path, dialect: Dialect) -> None:
    """OPEN_MAX transfers open (MISSION_COUNTs between as many pairs of systems), then frames that look for
    theirs: an item, a request, an ACK, a COUNT of a new pair (which closes the oldest), a CLEAR_ALL."""
    raws = []
    for k in range(OPEN_MAX):
        mav = apm.MAVLink(None, srcSystem=1 + k // 100, srcComponent=1)
        raws.append(apm.MAVLink_mission_count_message(100 + k % 100, 1, 3, 0).pack(mav))
    mav = apm.MAVLink(None, srcSystem=1, srcComponent=1)
    veh = apm.MAVLink(None, srcSystem=100, srcComponent=1)
    probes = [apm.MAVLink_mission_item_int_message(100, 1, 0, 0, 16, 0, 1, 0, 0, 0, 0, 1, 2, 3.0, 0).pack(mav),
              apm.MAVLink_mission_request_int_message(1, 1, 1, 0).pack(veh),
              apm.MAVLink_mission_ack_message(1, 1, 1, 0).pack(veh),
              apm.MAVLink_mission_count_message(200, 1, 3, 0).pack(apm.MAVLink(None, srcSystem=9, srcComponent=1)),
              apm.MAVLink_mission_clear_all_message(100, 1, 0).pack(mav)]
    frames = _frames_of(tmp_path, "open.tlog", raws + probes)
    tracker = MissionTracker(dialect)
    for f in frames[:OPEN_MAX]:
        tracker.feed(f)
    assert len(tracker.open) == OPEN_MAX
    for f in frames[OPEN_MAX:]:
        assert lines_run(lambda: tracker.feed(f)) < 400  # a scan of the open transfers ran 1,024 lines and more


def test_an_item_resent_many_times_keeps_its_frames_in_order_at_a_constant_cost(
        tmp_path: Path, dialect: Dialect, monkeypatch: pytest.MonkeyPatch) -> None:
    """MISSION_COUNT (10 items), the vehicle's MISSION_REQUEST_INT for seq 0, then seq 0 sent 300 times
    (pymavlink): each copy replaces the last (the vehicle still asks for 0) and the item lists all 300
    frames, records 3-302 in order. Every copy copied the frames listed so far (300 x 299 / 2 entries;
    100,000 resends took 11 s); now each frame is added once, however many came before it."""
    import importlib

    reconstruct = importlib.import_module("mavscope.analysis.mission.reconstruct")  # the package's name is a function
    copied = 0

    class Frames(list[int]):  # counts the entries a copy or an extension writes
        def __add__(self, other: list[int]) -> Frames:  # type: ignore[override]
            nonlocal copied
            copied += len(self) + len(other)
            return Frames(list.__add__(self, other))

        def extend(self, other: Iterable[int]) -> None:
            nonlocal copied
            more = list(other)
            copied += len(more)
            list.extend(self, more)

    real_item = reconstruct._item

    def item(name: str, fields: dict[str, object], record: int) -> Item:
        it = real_item(name, fields, record)
        it.frames = Frames(it.frames)
        return it

    monkeypatch.setattr(reconstruct, "_item", item)
    gcs = apm.MAVLink(None, srcSystem=255, srcComponent=190)
    veh = apm.MAVLink(None, srcSystem=1, srcComponent=1)
    raws = [apm.MAVLink_mission_count_message(1, 1, 10, 0).pack(gcs),
            apm.MAVLink_mission_request_int_message(255, 190, 0, 0).pack(veh)]
    for k in range(300):
        gcs.seq = k % 256
        raws.append(apm.MAVLink_mission_item_int_message(1, 1, 0, 3, 16, 0, 1, 0, 0, 0, 0, 0, 0, 10, 0).pack(gcs))
    tracker = MissionTracker(dialect)
    for f in _frames_of(tmp_path, "resent.tlog", raws):
        tracker.feed(f)
    [t] = tracker.finish().transfers
    assert t.items[0].frames == list(range(3, 303))
    assert copied <= 300


def test_broadcast_frames_cost_the_same_however_many_transfers_are_open(tmp_path: Path, dialect: Dialect) -> None:
    """Hostile: one GCS keeps OPEN_MAX uploads open (MISSION_COUNTs to as many targets), then sends items
    and a clear to 0/0 (system 0: every system) and a vehicle answers 0/0. A broadcast fits every open
    transfer of the sender; it reaches only those answering one broadcast COUNT (none here: the latest
    fits), so a frame does not visit every transfer (the scan it would be ran 1,024 lines and more)."""
    gcs = apm.MAVLink(None, srcSystem=255, srcComponent=190)
    raws = []
    for k in range(OPEN_MAX):
        gcs.seq = k % 256
        raws.append(apm.MAVLink_mission_count_message(1 + k % 250, 1 + k // 250, 3, 0).pack(gcs))
    veh = apm.MAVLink(None, srcSystem=7, srcComponent=1)
    probes = [apm.MAVLink_mission_item_int_message(0, 0, 0, 0, 16, 0, 1, 0, 0, 0, 0, 1, 2, 3.0, 0).pack(gcs),
              apm.MAVLink_mission_request_int_message(0, 0, 1, 0).pack(veh),
              apm.MAVLink_mission_ack_message(0, 0, 0, 0).pack(veh),
              apm.MAVLink_mission_clear_all_message(0, 0, 0).pack(gcs),
              apm.MAVLink_mission_ack_message(0, 0, 0, 0).pack(veh)]
    frames = _frames_of(tmp_path, "bcast.tlog", raws + probes)
    tracker = MissionTracker(dialect)
    for f in frames[:OPEN_MAX]:
        tracker.feed(f)
    for f in frames[OPEN_MAX:]:
        assert lines_run(lambda: tracker.feed(f)) < 400
