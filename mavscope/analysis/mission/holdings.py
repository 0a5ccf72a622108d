"""What each vehicle holds of each mission type as the capture goes on: the state the mission protocol
leaves on the vehicle, from the exchanges that change it or show it.

- an upload the vehicle accepted (MISSION_ACK MAV_MISSION_ACCEPTED from it) replaces what it held; an
  accepted upload of count 0 empties it (the spec: "a mission is cleared by uploading an empty mission",
  what QGroundControl and Mission Planner do to clear);
- an accepted MISSION_CLEAR_ALL empties that type (MAV_MISSION_TYPE_ALL: mission, fence and rally);
- an accepted MISSION_WRITE_PARTIAL_LIST replaces items start..end of what it held;
- a download with every item in the capture (acknowledged or not) shows what it holds.

Each change takes effect at the frame that decided it (the ACK; a download's last frame), so the latest
one is what the vehicle holds at the end of the capture; the earlier ones are its history.
"""

from __future__ import annotations

from dataclasses import dataclass

from mavscope.analysis.mission.model import (
    ACCEPTED_MISSING,
    COMPLETE,
    MAV_MISSION_ACCEPTED,
    MAV_MISSION_TYPE_ALL,
    UNACKNOWLEDGED,
    Addr,
    MissionLog,
    Transfer,
)

TYPES = (0, 1, 2)  # MAV_MISSION_TYPE_MISSION, _FENCE, _RALLY
UPLOAD, PARTIAL, DOWNLOAD, EMPTIED, CLEARED = "upload", "partial", "download", "empty-upload", "clear-all"
EMPTY_KINDS = (EMPTIED, CLEARED)


@dataclass(frozen=True, slots=True)
class Holding:
    """One change (or sight) of what a vehicle holds of a mission type."""

    vehicle: Addr
    mission_type: int
    kind: str  # UPLOAD, PARTIAL, DOWNLOAD (what it holds, seen), EMPTIED (accepted count 0), CLEARED
    record: int  # the frame that decided it
    time: float | None
    transfer: int | None  # index into MissionLog.transfers
    event: int | None  # index into MissionLog.events (CLEARED)

    @property
    def empty(self) -> bool:
        return self.kind in EMPTY_KINDS


def _decided(t: Transfer) -> tuple[int, float | None]:
    final = next((a for a in reversed(t.acks) if a.role == "final"), None)
    if final is not None:
        return final.record, final.time
    return (t.frames[-1] if t.frames else 0), t.end


def holdings(log: MissionLog) -> list[Holding]:
    """Every change and sight of what a vehicle holds, in the order of the frames that decided them."""
    out: list[Holding] = []
    for i, t in enumerate(log.transfers):
        record, time = _decided(t)
        if t.direction == "upload" and t.outcome in (COMPLETE, ACCEPTED_MISSING):
            kind = PARTIAL if t.partial else EMPTIED if t.count == 0 else UPLOAD
            out.append(Holding(t.receiver, t.mission_type, kind, record, time, i, None))
        elif t.direction == "download" and t.outcome in (COMPLETE, UNACKNOWLEDGED) and not t.partial:
            out.append(Holding(t.sender, t.mission_type, DOWNLOAD, record, time, i, None))
    for i, ev in enumerate(log.events):
        if ev.kind == "clear-all" and ev.ack is not None and ev.ack.result == MAV_MISSION_ACCEPTED:
            types = TYPES if ev.mission_type == MAV_MISSION_TYPE_ALL else (ev.mission_type,)
            out += [Holding(ev.ack.sender, m, CLEARED, ev.ack.record, ev.ack.time, None, i) for m in types]
    out.sort(key=lambda h: h.record)
    return out


def of(hs: list[Holding], sysid: int, mtype: int) -> list[Holding]:
    """Those of vehicle `sysid` (its autopilot holds the system's mission) and mission type `mtype`."""
    return [h for h in hs if h.vehicle[0] == sysid and h.mission_type == mtype]


def history(hs: list[Holding], log: MissionLog) -> list[int]:
    """The transfers (indices) with items that the vehicle held or showed before its last change."""
    return [h.transfer for h in hs[:-1] if h.transfer is not None and log.transfers[h.transfer].items]
