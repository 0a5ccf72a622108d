"""A link of mission-protocol parties, simulated, whose frames (pymavlink's encoding) make a tlog: the
expected answers of tests/analysis/test_mission_orderings.py come from the parties' own state, not from
mavscope.

`SimVehicle` is a mission server as the MAVLink mission protocol (mavlink.io/en/services/mission.html)
describes it and ArduPilot's MissionItemProtocol runs it: one upload at a time per mission type (another
GCS's MISSION_COUNT meanwhile is answered MAV_MISSION_DENIED), items requested one at a time in order,
MISSION_ACK ACCEPTED after the last item (at once for count 0), MISSION_CLEAR_ALL answered with an ACK
(`clear_acks` times: ArduPilot 2.x sent three), MISSION_REQUEST_LIST with MISSION_COUNT, each request with
its item (MISSION_ITEM for MISSION_REQUEST, MISSION_ITEM_INT for MISSION_REQUEST_INT),
MISSION_WRITE_PARTIAL_LIST by requesting items start..end. It answers a message whose target is its
system or 0 and its component or 0 (MAVLink routing); `answer_broadcast` addresses its answers to 0/0.

`SimGcs` is a client: `upload` sends MISSION_CLEAR_ALL (if asked) and MISSION_COUNT back to back without
waiting (Mission Planner, MAVProxy's old wp module), answers each request with the item it names
(MISSION_ITEM when `legacy`, MISSION_ITEM_INT otherwise); `download` sends MISSION_REQUEST_LIST and
requests `window` items at a time (MAVProxy asks for 5, QGroundControl and Mission Planner for 1), then
ACKs ACCEPTED. Every party hears every frame (one broadcast link); `drop` loses chosen frames before a
party receives them (the capture, taken at the sender, still holds them); an idle party re-requests what
it waits for, as after its timeout.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as v20

from tests.support.builders import write_tlog

T0 = 1_760_000_000.0
ACCEPTED, NO_SPACE, DENIED = 0, 4, 14  # MAV_MISSION_RESULT
Addr = tuple[int, int]


class Link:
    def __init__(self) -> None:
        self.parties: list[Party] = []
        self.frames: list[tuple[float, bytes]] = []
        self.queue: deque[tuple[Party, Any, int]] = deque()
        self.t = T0
        self.drop: Callable[[Party, Any], bool] = lambda party, msg: False

    def send(self, who: Party, name: str, *args: object) -> int:
        msg = getattr(who.mav, f"{name.lower()}_encode")(*args)
        self.t += 0.01
        self.frames.append((self.t, msg.pack(who.mav)))
        who.mav.seq = (who.mav.seq + 1) % 256
        self.queue.append((who, msg, len(self.frames)))
        return len(self.frames)

    def run(self, limit: int = 10_000) -> None:
        for _ in range(limit):
            if not self.queue:
                self.t += 2.0  # the parties' timeouts pass
                for p in self.parties:
                    p.idle()
                if not self.queue:
                    return
                continue
            src, msg, _ = self.queue.popleft()
            for p in self.parties:
                if p is not src and not self.drop(p, msg):
                    p.hear(src.addr, msg)

    def tlog(self, path: Path) -> str:
        return write_tlog(path.parent, self.frames, path.name)


class Party:
    def __init__(self, link: Link, sysid: int, compid: int) -> None:
        self.link, self.addr = link, (sysid, compid)
        self.mav = v20.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        link.parties.append(self)

    def mine(self, msg: Any) -> bool:
        """A message for this party: its target is this system or 0, this component or 0."""
        return msg.target_system in (0, self.addr[0]) and msg.target_component in (0, self.addr[1])

    def send(self, name: str, *args: object) -> int:
        return self.link.send(self, name, *args)

    def hear(self, src: Addr, msg: Any) -> None:
        raise NotImplementedError

    def idle(self) -> None:
        pass


def item_args(seq: int, point: tuple[float, float, float], legacy: bool, mtype: int) -> tuple[str, tuple]:
    lat, lon, alt = point
    if legacy:
        return "MISSION_ITEM", (seq, 3, 16, 0, 1, 0, 0, 0, 0, lat, lon, alt, mtype)
    return "MISSION_ITEM_INT", (seq, 6, 16, 0, 1, 0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), alt, mtype)


class SimVehicle(Party):
    def __init__(self, link: Link, sysid: int = 1, compid: int = 1, legacy: bool = False,
                 answer_broadcast: bool = False, clear_acks: int = 1, capacity: int = 700,
                 components: tuple[int, ...] = ()) -> None:
        super().__init__(link, sysid, compid)
        self.components = components  # other target components it takes as its own (PX4: 190, the mission planner)
        self.legacy, self.answer_broadcast = legacy, answer_broadcast
        self.clear_acks, self.capacity = clear_acks, capacity
        self.held: dict[int, dict[int, Any]] = {0: {}, 1: {}, 2: {}}
        self.rx: dict[int, dict[str, Any]] = {}  # mission type -> the upload being received
        self.log: list[tuple] = []  # what it did: ("upload", gcs, type, count, result), ("clear", gcs, type, result)

    def to(self, src: Addr) -> Addr:
        return (0, 0) if self.answer_broadcast else src

    def mine(self, msg: Any) -> bool:
        return super().mine(msg) or (msg.target_system == self.addr[0] and msg.target_component in self.components)

    def request(self, rx: dict[str, Any]) -> None:
        self.send("MISSION_REQUEST" if self.legacy else "MISSION_REQUEST_INT", *self.to(rx["gcs"]), rx["next"],
                  rx["type"])

    def hear(self, src: Addr, msg: Any) -> None:
        name = msg.get_type()
        if not hasattr(msg, "target_system") or not self.mine(msg) or name == "MISSION_CURRENT":
            return
        mtype = getattr(msg, "mission_type", 0)
        if name in ("MISSION_COUNT", "MISSION_WRITE_PARTIAL_LIST"):
            rx = self.rx.get(mtype)
            if rx is not None and rx["gcs"] != src:
                self.send("MISSION_ACK", *self.to(src), DENIED, mtype)
                self.log.append(("upload", src, mtype, getattr(msg, "count", None), DENIED))
                return
            first, last = (0, msg.count - 1) if name == "MISSION_COUNT" else (msg.start_index, msg.end_index)
            if name == "MISSION_COUNT" and msg.count > self.capacity:
                self.send("MISSION_ACK", *self.to(src), NO_SPACE, mtype)
                self.log.append(("upload", src, mtype, msg.count, NO_SPACE))
                return
            if last < first:  # count 0: the mission emptied at once
                self.held[mtype] = {}
                self.send("MISSION_ACK", *self.to(src), ACCEPTED, mtype)
                self.log.append(("upload", src, mtype, 0, ACCEPTED))
                return
            self.rx[mtype] = {"gcs": src, "type": mtype, "next": first, "last": last, "items": {},
                              "partial": name != "MISSION_COUNT", "count": last + 1}
            self.request(self.rx[mtype])
        elif name in ("MISSION_ITEM", "MISSION_ITEM_INT"):
            rx = self.rx.get(mtype)
            if rx is None or rx["gcs"] != src or msg.seq != rx["next"]:
                return  # not asked for (a copy, or another GCS's): ArduPilot ignores or NACKs it
            rx["items"][msg.seq] = msg
            rx["next"] += 1
            if rx["next"] <= rx["last"]:
                self.request(rx)
                return
            del self.rx[mtype]
            self.held[mtype] = {**self.held[mtype], **rx["items"]} if rx["partial"] else dict(rx["items"])
            self.send("MISSION_ACK", *self.to(src), ACCEPTED, mtype)
            self.log.append(("partial" if rx["partial"] else "upload", src, mtype, rx["count"], ACCEPTED))
        elif name == "MISSION_CLEAR_ALL":
            for m in ((0, 1, 2) if mtype == 255 else (mtype,)):
                self.held[m] = {}
            for _ in range(self.clear_acks):
                self.send("MISSION_ACK", *self.to(src), ACCEPTED, mtype)
            self.log.append(("clear", src, mtype, ACCEPTED))
        elif name == "MISSION_REQUEST_LIST":
            self.send("MISSION_COUNT", *self.to(src), len(self.held[mtype]), mtype)
        elif name in ("MISSION_REQUEST", "MISSION_REQUEST_INT") and msg.seq in self.held[mtype]:
            it = self.held[mtype][msg.seq]
            point = (it.x, it.y) if it.get_type() == "MISSION_ITEM" else (it.x / 1e7, it.y / 1e7)
            kind, args = item_args(msg.seq, (*point, it.z), name == "MISSION_REQUEST", mtype)
            self.send(kind, *self.to(src), *args)

    def idle(self) -> None:
        for rx in self.rx.values():  # the item did not come: ask again (ArduPilot after 1 s)
            self.request(rx)


class SimGcs(Party):
    def __init__(self, link: Link, sysid: int = 255, compid: int = 190, legacy: bool = False, window: int = 1) -> None:
        super().__init__(link, sysid, compid)
        self.legacy, self.window = legacy, window
        self.plans: dict[int, list[tuple[float, float, float]]] = {}
        self.got: dict[int, dict[str, Any]] = {}  # mission type -> download in progress
        self.downloads: list[tuple[Addr, int, int]] = []  # (vehicle, type, items) it completed
        self.target: Addr = (1, 1)

    def upload(self, target: Addr, mtype: int, points: list[tuple[float, float, float]], clear_first: bool = False,
               partial: tuple[int, int] | None = None) -> None:
        self.target, self.plans[mtype] = target, points
        if clear_first:
            self.send("MISSION_CLEAR_ALL", *target, mtype)
        if partial is not None:
            self.send("MISSION_WRITE_PARTIAL_LIST", *target, *partial, mtype)
        else:
            self.send("MISSION_COUNT", *target, len(points), mtype)

    def download(self, target: Addr, mtype: int) -> None:
        self.target = target
        self.send("MISSION_REQUEST_LIST", *target, mtype)

    def ask(self, vehicle: Addr, mtype: int) -> None:
        d = self.got[mtype]
        for seq in [s for s in range(d["count"]) if s not in d["items"]][:self.window]:
            self.send("MISSION_REQUEST" if self.legacy else "MISSION_REQUEST_INT", *vehicle, seq, mtype)

    def hear(self, src: Addr, msg: Any) -> None:
        name = msg.get_type()
        if not hasattr(msg, "target_system") or not self.mine(msg):
            return
        mtype = getattr(msg, "mission_type", 0)
        if name in ("MISSION_REQUEST", "MISSION_REQUEST_INT") and msg.seq < len(self.plans.get(mtype, [])):
            kind, args = item_args(msg.seq, self.plans[mtype][msg.seq], self.legacy, mtype)
            self.send(kind, *self.target, *args)
        elif name == "MISSION_COUNT":
            self.got[mtype] = {"count": msg.count, "items": {}, "from": src}
            if msg.count == 0:
                self.finish(src, mtype)
            else:
                self.ask(src, mtype)
        elif name in ("MISSION_ITEM", "MISSION_ITEM_INT") and mtype in self.got:
            d = self.got[mtype]
            if msg.seq not in d["items"]:
                d["items"][msg.seq] = msg
                if len(d["items"]) == d["count"]:
                    self.finish(src, mtype)
                elif len(d["items"]) % self.window == 0:
                    self.ask(src, mtype)

    def finish(self, vehicle: Addr, mtype: int) -> None:
        d = self.got.pop(mtype)
        self.send("MISSION_ACK", *vehicle, ACCEPTED, mtype)
        self.downloads.append((vehicle, mtype, d["count"]))
