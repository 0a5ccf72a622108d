"""Small MAVLink flows built with pymavlink for the analysis tests, written as a tlog.

Each test states what it built; the expected answers come from that construction, never from mavscope.
The messages and the file writers are tests/support/builders.py's.
"""

from __future__ import annotations

from collections.abc import Callable

from pymavlink.dialects.v20 import ardupilotmega as v2

from tests.support.builders import command_long_msg, heartbeat_msg
from tests.support.builders import tlog as tlog
from tests.support.builders import write_tlog as write_tlog
from tests.support.builders import write_udp_pcap as write_udp_pcap

T0 = 1_773_482_400.0  # 2026-03-14T10:00:00Z


class Sender:
    """One MAVLink sender with its own sequence counter (a second Sender with the same ids is a second
    counter, as Mission Planner's REQUEST_DATA_STREAM channel)."""

    def __init__(self, sysid: int, compid: int, seq: int = 0) -> None:
        self.mav = v2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.mav.seq = seq

    def pack(self, msg: object) -> bytes:
        """The next frame of this sender (pymavlink's pack does not advance the counter; send would)."""
        frame = bytes(msg.pack(self.mav))  # type: ignore[attr-defined]
        self.mav.seq = (self.mav.seq + 1) % 256
        return frame

    def skip(self, n: int = 1) -> None:
        """Lose the next `n` frames (their sequence numbers are used, the frames never arrive)."""
        self.mav.seq = (self.mav.seq + n) % 256


def heartbeat(gcs: bool = False) -> object:
    """A ground rover's HEARTBEAT (MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_ARDUPILOTMEGA), or a GCS's."""
    return heartbeat_msg(6, 8) if gcs else heartbeat_msg(10, 3)


def manual_control(x: int = 0, y: int = 0, z: int = 500, r: int = 0) -> object:
    return v2.MAVLink_manual_control_message(1, x, y, z, r, 0)


def command_long(command: int = 400, p1: float = 1.0, target: int = 1) -> object:
    return command_long_msg(command, p1, target_system=target)


def run_sent_again(gcs: Sender, is_command: Callable[[int], bool], again_at: int,
                   neutral: Callable[[int], object] = lambda i: manual_control(x=i), frames: int = 400
                   ) -> list[tuple[float, bytes]]:
    """A GCS's `frames` frames 0.05 s apart (frame i: sequence i % 256, tlog record i + 1): COMMAND_LONG
    400 + i where `is_command(i)`, `neutral(i)` otherwise; just before its frame `again_at` the commands sent
    so far are sent again, byte for byte, 0.01 s earlier (a recorded run replayed)."""
    entries: list[tuple[float, bytes]] = []
    recorded: list[bytes] = []
    for i in range(frames):
        if i == again_at:
            entries += [(T0 + i * 0.05 - 0.01, f) for f in recorded]
        frame = gcs.pack(command_long(400 + i) if is_command(i) else neutral(i))
        if is_command(i):
            recorded.append(frame)
        entries.append((T0 + i * 0.05, frame))
    return entries
