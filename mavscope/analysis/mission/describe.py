"""One sentence for each transfer and event: why a transfer ended as it did, what an operation got back."""

from __future__ import annotations

from mavscope.analysis.mission.model import (
    ABANDONED,
    ACCEPTED_MISSING,
    CANCELLED,
    COMPLETE,
    NACK,
    OPEN_MAX,
    UNACKNOWLEDGED,
    Addr,
    Event,
    Transfer,
)
from mavscope.analysis.runs import runs
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.semantics import enum_name


def result_name(dialect: Dialect, value: int | None) -> str | None:
    return None if value is None else enum_name(dialect, "MAV_MISSION_RESULT", value)


def addr(a: Addr) -> str:
    return f"{a[0]}/{a[1]}"


def ranges(seqs: list[int]) -> str:
    """"0..92, 95" for [0, 1, ..., 92, 95]."""
    return run_text(runs(seqs))


def run_text(spans: list[list[int]]) -> str:
    """"0..92, 95" for [[0, 92], [95, 95]]."""
    return ", ".join(str(a) if a == b else f"{a}..{b}" for a, b in spans)


_WHY = {"restarted": "a new MISSION_COUNT or MISSION_REQUEST_LIST between the two systems followed",
        "timeout": "no frame of it for longer than the protocol timeout",
        "evicted": f"more transfers were open at once than mavscope follows ({OPEN_MAX:,}): this one, the newest "
                   "not yet answered, was given up",
        "end": "the capture ends"}


def reason(t: Transfer, dialect: Dialect) -> str:
    missing = t.missing
    span = f"items {t.first}..{t.count - 1} (a partial upload)" if t.partial else f"{t.count} items"
    got = f"{len(t.items)} of {span}"
    miss = f"items missing from the capture: {run_text(missing)}" if missing else ""
    silent = f"; {addr(t.receiver)} sent no frame in this capture" if t.receiver_silent else ""
    if t.outcome == COMPLETE:
        text = "accepted"
    elif t.outcome == ACCEPTED_MISSING:
        text = f"accepted, but {miss}"
    elif t.outcome == NACK:
        text = f"NACK {result_name(dialect, t.result)} from {addr(t.receiver)}; {got}"
    elif t.outcome == CANCELLED:
        have = f"items {ranges(sorted(t.items))} of {t.count}" if t.items else f"none of {t.count} items"
        text = f"cancelled by the sender {addr(t.sender)} with {result_name(dialect, t.result)} after {have}"
    elif t.outcome == UNACKNOWLEDGED:
        have = f"all {span} in the capture" if t.count > t.first else "count 0 (nothing to request)"
        text = f"{have}, no MISSION_ACK from {addr(t.receiver)} ({_WHY.get(t.closed, t.closed)})"
    elif t.outcome == ABANDONED:
        text = f"abandoned: no MISSION_ACK ({_WHY.get(t.closed, t.closed)}); {got}; {miss}"
    else:
        text = t.outcome
    went_on = [a for a in t.acks if a.role == "continued"]
    if went_on:
        names = ", ".join(f"{result_name(dialect, a.result)} (frame {a.record})" for a in went_on)
        text += f"; the transfer went on after NACK {names}"
    return text + silent


def event_text(ev: Event, dialect: Dialect) -> str:
    mtype = enum_name(dialect, "MAV_MISSION_TYPE", ev.mission_type)
    who = f"from {addr(ev.sender)} to {addr(ev.target)}"
    answer = f"MISSION_ACK {result_name(dialect, ev.ack.result)}" if ev.ack is not None else "no MISSION_ACK"
    if ev.addressed is not None and ev.addressed != ev.target:
        who += f" (addressed to {addr(ev.addressed)})"
    if ev.kind == "clear-all":
        again = f" ({len(ev.repeats)} more time(s))" if ev.repeats else ""
        return f"MISSION_CLEAR_ALL {mtype} {who}: {answer}{again}"
    if ev.kind == "request-list":
        return f"MISSION_REQUEST_LIST {mtype} {who} answered by no MISSION_COUNT: {answer}"
    if ev.kind == "set-current":
        if ev.confirmed:
            got = f"MISSION_CURRENT reports seq {ev.reported}"
        elif ev.reported is not None:
            got = f"not confirmed: MISSION_CURRENT reports seq {ev.reported}"
        else:
            got = "no MISSION_CURRENT from the target followed"
        return f"MISSION_SET_CURRENT seq {ev.seq} {who}: {got}"
    if ev.kind == "unmatched-ack":
        return f"MISSION_ACK {result_name(dialect, ev.ack.result if ev.ack else None)} {mtype} {who} " \
               f"answers no transfer or operation in the capture"
    msgs = ", ".join(f"{n} {name}" for name, n in sorted(ev.messages.items()))
    return f"{msgs} {mtype} {who} outside any transfer (seqs {ranges(sorted(set(ev.seqs)))}): " \
           f"its MISSION_COUNT is not in the capture"
