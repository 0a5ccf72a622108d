"""Which mission, fence and rally points a .plan (and `mavscope track`) shows: what one vehicle holds at the
end of the capture (holdings.py), or, where no exchange the vehicle accepted is in the capture, the best
transfer there is (`export.pick`).

After an accepted empty upload or MISSION_CLEAR_ALL the vehicle holds nothing of that type: the plan's
section is empty, and `Section.cleared` says when and by what, with the transfers it held before (its
history). `--plan-transfer N` exports transfer N for its type instead (history on request).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TypedDict

from mavscope.analysis.mission.describe import addr, run_text
from mavscope.analysis.mission.holdings import DOWNLOAD, EMPTIED, PARTIAL, Holding, history, holdings, of
from mavscope.analysis.mission.model import ACCEPTED_MISSING, COMPLETE, Addr, MissionLog, Transfer
from mavscope.analysis.runs import runs

WHAT = {0: "mission", 1: "fence", 2: "rally"}
HOW = {EMPTIED: "an accepted upload of 0 items", "clear-all": "MISSION_CLEAR_ALL accepted",
       DOWNLOAD: "a download of 0 items"}


class Cleared(TypedDict):
    """The vehicle holds none of a mission type since the frame `frame` (at `at`): `how` (holdings.EMPTIED,
    CLEARED, DOWNLOAD of 0 items) by transfer or event `transfer` / `event` (numbered from 1), after holding
    the transfers `history` (their numbers)."""

    how: str
    at: float | None
    frame: int
    transfer: int | None
    event: int | None
    history: list[int]


@dataclass
class Section:
    """The mission, fence or rally of the plan."""

    transfer: int | None = None  # index into MissionLog.transfers of what is exported
    items: Transfer | None = None  # what is exported (a partial upload laid over what it changed)
    cleared: Cleared | None = None  # the vehicle holds nothing: when, by what, what it held before


@dataclass
class Choice:
    vehicle: Addr | None
    sections: dict[int, Section]
    warnings: list[str] = field(default_factory=list)


def vehicle_end(t: Transfer) -> Addr:
    """The vehicle end of a transfer: the receiver of an upload, the sender of a download."""
    return t.sender if t.direction == "download" else t.receiver


def _pick(log: MissionLog, mtype: int, sysid: int | None) -> int | None:
    """The transfer of `mtype` to export when none the vehicle accepted or showed is in the capture: the
    last complete one with items, else the last with every item, else the last with any item."""
    best: tuple[int, int] | None = None
    for i, t in enumerate(log.transfers):
        if t.mission_type == mtype and t.items and (sysid is None or vehicle_end(t)[0] in (sysid, 0)):
            rank = (2 if t.complete else 1 if not t.missing else 0, i)
            best = rank if best is None or rank > best else best
    return None if best is None else best[1]


def _vehicle(log: MissionLog, hs: list[Holding]) -> Addr | None:
    """The vehicle whose plan this is: the last to change (or show) its mission, else its fence or rally."""
    for h in reversed(hs):
        if h.mission_type == 0:
            return h.vehicle
    if hs:
        return hs[-1].vehicle
    i = next((i for i in (_pick(log, m, None) for m in WHAT) if i is not None), None)
    return None if i is None else vehicle_end(log.transfers[i])


def _number(i: int | None) -> int | None:
    return None if i is None else i + 1  # as the text output numbers transfers and events


def _cleared(log: MissionLog, mine: list[Holding], what: str, warnings: list[str]) -> Cleared:
    last = mine[-1]
    before = history(mine, log)
    doc: Cleared = {"how": last.kind, "at": last.time, "frame": last.record, "transfer": _number(last.transfer),
                    "event": _number(last.event), "history": [i + 1 for i in before]}
    by = f"transfer {last.transfer + 1}" if last.transfer is not None else f"event {_number(last.event)}"
    if before:
        held = log.transfers[before[-1]]
        warnings.append(f"the vehicle {addr(last.vehicle)} holds no {what} since frame {last.record} "
                        f"({HOW.get(last.kind, last.kind)}, {by}): the {what} of transfer {before[-1] + 1} "
                        f"({len(held.items)} items) is history, not exported (--plan-transfer {before[-1] + 1} "
                        f"exports it)")
    return doc


def _overlay(log: MissionLog, mine: list[Holding], what: str, warnings: list[str]) -> Transfer:
    """An accepted partial upload laid over what the vehicle held before it."""
    n = mine[-1].transfer or 0
    part = log.transfers[n]
    span = run_text(runs(sorted(part.items)))
    base = next((h for h in reversed(mine[:-1]) if h.kind != PARTIAL), None)
    if base is None or base.transfer is None:
        warnings.append(f"the exported {what} is only items {span} (the partial upload of transfer {n + 1}): "
                        f"what the vehicle held before is not in the capture")
        return part
    held = log.transfers[base.transfer]
    warnings.append(f"the exported {what} is transfer {base.transfer + 1} with items {span} replaced by the "
                    f"partial upload of transfer {n + 1}")
    return replace(part, items={**held.items, **part.items}, first=0, partial=False,
                   count=max(held.count, part.count))


def choose(log: MissionLog, chosen: int | None = None) -> Choice:
    """What the plan exports; `chosen` (an index into log.transfers) replaces the choice for its type."""
    hs = holdings(log)
    vehicle = _vehicle(log, hs)
    if chosen is not None:
        vehicle = vehicle_end(log.transfers[chosen])
    sysid = None if vehicle is None else vehicle[0]
    choice = Choice(vehicle, {})
    others = sorted({h.vehicle[0] for h in hs} - {sysid})
    if others and sysid is not None:
        systems = ", ".join(map(str, others))
        choice.warnings.append(f"the capture holds the missions of other vehicles too (system {systems}): this plan "
                               f"is system {sysid}'s")
    for mtype, what in WHAT.items():
        sec = choice.sections[mtype] = Section()
        if chosen is not None and log.transfers[chosen].mission_type == mtype:
            sec.transfer, sec.items = chosen, log.transfers[chosen]
            continue
        mine = of(hs, sysid, mtype) if sysid is not None else []
        if not mine:
            sec.transfer = _pick(log, mtype, sysid)
        elif mine[-1].empty or not log.transfers[mine[-1].transfer or 0].items:
            sec.cleared = _cleared(log, mine, what, choice.warnings)
            continue
        else:
            sec.transfer = mine[-1].transfer
            later = [i for i, t in enumerate(log.transfers) if i > (sec.transfer or 0) and t.mission_type == mtype
                     and t.direction == "upload" and t.items and t.outcome not in (COMPLETE, ACCEPTED_MISSING)
                     and vehicle_end(t)[0] == sysid]
            if later:
                choice.warnings.append(f"an upload of the {what} the vehicle did not accept (transfer {later[-1] + 1})"
                                       f" followed the exported one: it may hold part of it")
        if sec.transfer is not None:
            t = log.transfers[sec.transfer]
            sec.items = _overlay(log, mine, what, choice.warnings) if mine and mine[-1].kind == PARTIAL else t
    return choice
