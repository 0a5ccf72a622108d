"""Mission exchanges written as a tlog or a raw stream by pymavlink (an independent implementation), for
tests whose expected answers follow from how the exchange was built."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

from pymavlink.dialects.v10 import ardupilotmega as v10
from pymavlink.dialects.v20 import ardupilotmega as v20

from tests.support.builders import write_raw, write_tlog

T0 = 1_760_000_000.0  # capture time of the first frame (Unix seconds)


class Exchange:
    """Frames of a GCS (255/190 unless told) and a vehicle (1/1), each with a capture time; record n of the
    tlog is the n-th frame added (1-based)."""

    def __init__(self, version: int = 2, gcs: tuple[int, int] = (255, 190), vehicle: tuple[int, int] = (1, 1)) -> None:
        self.mod: ModuleType = v20 if version == 2 else v10
        self.gcs = self.mod.MAVLink(None, srcSystem=gcs[0], srcComponent=gcs[1])
        self.veh = self.mod.MAVLink(None, srcSystem=vehicle[0], srcComponent=vehicle[1])
        self.t = T0
        self.frames: list[tuple[float, bytes]] = []

    def wait(self, seconds: float) -> Exchange:
        self.t += seconds
        return self

    def send(self, side: str, name: str, *args: object, dt: float = 0.005) -> int:
        """Encode message `name` (pymavlink's <name>_encode arguments) from "gcs" or "veh"; its record number."""
        mav = self.gcs if side == "gcs" else self.veh
        msg = getattr(mav, f"{name.lower()}_encode")(*args)
        self.t += dt
        self.frames.append((self.t, msg.pack(mav)))
        mav.seq = (mav.seq + 1) % 256  # as MAVLink.send() does after packing
        return len(self.frames)

    def copy(self, record: int, dt: float = 0.0002) -> int:
        """The bytes of an earlier record again (a link or capture duplicate: same MAVLink seq)."""
        self.t += dt
        self.frames.append((self.t, self.frames[record - 1][1]))
        return len(self.frames)

    def heartbeats(self, vehicle_type: int = 2, autopilot: int = 12) -> None:
        self.send("veh", "HEARTBEAT", vehicle_type, autopilot, 0, 0, 4, 3)
        self.send("gcs", "HEARTBEAT", 6, 8, 0, 0, 4, 3)

    def tlog(self, path: Path) -> str:
        return write_tlog(path.parent, self.frames, path.name)

    def raw(self, path: Path) -> str:
        return write_raw(path.parent, [raw for _, raw in self.frames], path.name)


def item_int(x: Exchange, side: str, target: tuple[int, int], seq: int, command: int, lat: float, lon: float,
             alt: float, frame: int = 6, params: tuple[float, float, float, float] = (0, 0, 0, 0),
             mission_type: int = 0) -> int:
    """MISSION_ITEM_INT with degrees given as floats (sent as degE7)."""
    return x.send(side, "MISSION_ITEM_INT", target[0], target[1], seq, frame, command, 0, 1, *params,
                  round(lat * 1e7), round(lon * 1e7), alt, mission_type)
