"""CommandMatcher against its definition, and what a frame costs it whatever number of commands wait.

The reference below is the matching rule as the module's docstring states it, written as the plain scan
over the waiting commands it was until stop 23 (then 200,000 unanswered commands took `commands` 68 s in
that scan alone: every frame looked at up to 4,096 waiting commands)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from mavscope.analysis import command_log
from mavscope.analysis.command_log import PENDING_MAX, Command, CommandMatcher
from mavscope.mavlink.dialect import Dialect
from tests.support.cost import lines_run


class Reference:
    """The docstring's rule, scanning every waiting command: a retry is the same message, command, sender and
    target still waiting; an ACK answers the oldest waiting command of its id whose target is the ACK's
    system (or 0) and component (or 0) and whose sender is the system and component the ACK names (where
    it names them); IN_PROGRESS answers without completing; past `cap` waiting, the
    one sent last before the new one is given up (with a cap of 1, the one waiting)."""

    def __init__(self, cap: int) -> None:
        self.cap = cap
        self.pending: list[dict[str, Any]] = []

    def add(self, ev: tuple) -> tuple[bool, list[int]]:
        if ev[0] == "cmd":
            _, msg, cmd_id, sender, target, record = ev
            for c in self.pending:
                if (c["msg"], c["cmd"], c["sender"], c["target"]) == (msg, cmd_id, sender, target):
                    c["retries"] += 1
                    c["frames"].append(record)
                    return False, []
            self.pending.append({"msg": msg, "cmd": cmd_id, "sender": sender, "target": target, "frames": [record],
                                 "retries": 0, "result": None, "progress": []})
            # past the cap the newest waiting but the new one is given up (a flood gives up its own)
            return True, [self.pending.pop(-2)["frames"][0]] if len(self.pending) > self.cap else []
        _, cmd_id, (sysid, compid), to_sys, to_comp, result, record = ev
        for c in self.pending:
            if c["cmd"] == cmd_id and c["target"][0] in (0, sysid) and c["target"][1] in (0, compid) \
                    and (not to_sys or to_sys == c["sender"][0]) and (not to_comp or to_comp == c["sender"][1]):
                c["frames"].append(record)
                if result == command_log.MAV_RESULT_IN_PROGRESS:
                    c["progress"].append(7)
                    return False, []
                c["result"] = result
                c["frames"].pop()  # an ACK is the command's ack_frame, not one of its frames
                self.pending.remove(c)
                return False, [c["frames"][0]]
        return False, []


def _frame(name: str, sysid: int, compid: int, record: int) -> Any:
    return SimpleNamespace(msgdef=SimpleNamespace(name=name), sysid=sysid, compid=compid, record=record,
                           time=record / 10, src=None)


def _feed(m: CommandMatcher, ev: tuple) -> tuple[Command | None, list[Command]]:
    if ev[0] == "cmd":
        _, msg, cmd_id, sender, target, record = ev
        fields: dict[str, object] = {"command": cmd_id, "target_system": target[0], "target_component": target[1],
                                     "param1": 1.0, "confirmation": 0}
        if msg == "COMMAND_INT":
            fields = {**fields, "x": 0, "y": 0, "frame": 0}
        return m.add(_frame(msg, *sender, record), fields)
    _, cmd_id, sender, to_sys, to_comp, result, record = ev
    return m.add(_frame("COMMAND_ACK", *sender, record), {"command": cmd_id, "result": result, "progress": 7,
                                                           "target_system": to_sys, "target_component": to_comp})


PARTIES = st.sampled_from([(255, 190), (66, 190), (255, 1), (1, 1), (1, 0), (2, 1), (0, 0)])
COMMANDS = st.tuples(st.just("cmd"), st.sampled_from(["COMMAND_LONG", "COMMAND_INT"]), st.sampled_from([400, 16]),
                     PARTIES, st.sampled_from([(0, 0), (1, 0), (1, 1), (2, 1), (0, 1)]))
ACKS = st.tuples(st.just("ack"), st.sampled_from([400, 16]), PARTIES, st.sampled_from([0, 255, 66, 1]),
                 st.sampled_from([0, 190, 1]), st.sampled_from([0, 4, 5]))


@settings(max_examples=400, deadline=None)
@example(events=[("cmd", "COMMAND_LONG", 400, (255, 190), (1, 1)), ("cmd", "COMMAND_LONG", 400, (255, 190), (0, 0)),
                 ("ack", 400, (1, 1), 0, 0, 0)], cap=4)  # the older command answered, though to another target
@given(events=st.lists(st.one_of(COMMANDS, ACKS), max_size=60), cap=st.integers(1, 6))
def test_the_matcher_is_its_definition(events: list[tuple], cap: int, dialect: Dialect) -> None:
    ref = Reference(cap)
    saved = command_log.PENDING_MAX
    command_log.PENDING_MAX = cap
    try:
        m = CommandMatcher(dialect)
        for record, ev in enumerate(events, 1):
            ev = (*ev, record)
            new, done = _feed(m, ev)
            want_new, want_done = ref.add(ev)
            assert (new is not None, [c.frames[0] for c in done]) == (want_new, want_done), ev
        left = m.finish()
    finally:
        command_log.PENDING_MAX = saved
    assert [(c.frames, c.retries, c.progress) for c in left] == \
        [(c["frames"], c["retries"], c["progress"]) for c in ref.pending]


@pytest.mark.parametrize("frame", [
    ("cmd", "COMMAND_LONG", 400, (255, 190), (200, 1)),  # new: pushes out the newest but itself
    ("cmd", "COMMAND_LONG", 400, (255, 190), (9, 9)),  # a retry of the newest
    ("ack", 400, (200, 1), 0, 0, 0),  # answers nothing waiting for 200/1 (all wait for 1..16 / 1..255)
    ("ack", 400, (16, 255), 0, 0, 0),  # answers the newest
    ("ack", 400, (1, 1), 77, 0, 0),  # names a sender nothing came from
    ("ack", 400, (1, 1), 0, 77, 0),  # names only a sender component
    ("ack", 400, (1, 1), 255, 190, 0),  # answers the oldest
], ids=["new", "retry", "ack-unmatched", "ack-newest", "ack-other-sender", "ack-component", "ack-oldest"])
def test_a_frame_costs_the_same_however_many_commands_wait(frame: tuple, dialect: Dialect) -> None:
    m = CommandMatcher(dialect)
    for i in range(PENDING_MAX - 1):
        _feed(m, ("cmd", "COMMAND_LONG", 400, (255, 190), (1 + i // 255, 1 + i % 255), i))
    _feed(m, ("cmd", "COMMAND_LONG", 400, (255, 190), (9, 9), PENDING_MAX))
    assert lines_run(lambda: _feed(m, (*frame, PENDING_MAX + 1))) < 120  # the scan took 4,096 and more
