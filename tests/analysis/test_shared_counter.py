"""Ids that number their frames on one sequence counter (one program sending as several, as BlueOS's
mavlink-server and ArduSub's companion computer do in the real tlogs: tests/crosscheck/test_real_sequence.py):
the numbers one id skips, the others used, and are not frames lost.

The flows are built here with pymavlink: one MAVLink object packs the frames of both ids (its source
component switched between them), so they share its counter, as in the C library where the counter
belongs to the channel. Every expected loss is the count of numbers the test itself skipped, charged to the
id whose frame came after the skipped number. Both engines (native when built, and MAVSCOPE_PURE) must give
the same answers.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.analysis.sequence import SHARED_MIN, SeqTracker
from tests.conftest import Cli
from tests.support.flows import T0, Sender, heartbeat, write_tlog

ENGINES = [pytest.param({}, id="default"), pytest.param({"MAVSCOPE_PURE": "1"}, id="pure")]


def as_id(sender: Sender, compid: int, msg: object) -> bytes:
    """The next frame of `sender`'s counter, sent as component `compid`."""
    mav = sender.mav
    own, mav.srcComponent = mav.srcComponent, compid
    try:
        return sender.pack(msg)
    finally:
        mav.srcComponent = own


def attitude() -> object:
    return v2.MAVLink_attitude_message(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def system_time() -> object:
    return v2.MAVLink_system_time_message(0, 0)


def _links(cli: Cli, path: str, environ: dict[str, str]) -> tuple[dict[str, int], dict[str, list[dict]]]:
    doc = cli.json("stats", path, environ=environ)
    lost = {f"{lk['sysid']}/{lk['compid']}": lk["lost"] for lk in doc["links"]}
    found: dict[str, list[dict]] = {}
    for f in doc["findings"]:
        found.setdefault(f["code"], []).append(f)
    return lost, found


@pytest.mark.parametrize("environ", ENGINES)
def test_two_ids_on_one_counter_lose_what_the_counter_lost(cli: Cli, tmp_path: Path,
                                                           environ: dict[str, str]) -> None:
    """30 cycles of: the vehicle 1/1 (a counter of its own) sends 5 ATTITUDE, the companion sends a
    HEARTBEAT as 1/194 and 3 SYSTEM_TIME as 1/220 on one counter, the ground station 255/190 (its own
    counter) a HEARTBEAT. The companion's counter loses one frame just before 1/194's HEARTBEAT of cycle 10
    (charged to 1/194) and one just before 1/220's second frame of cycle 20 (charged to 1/220); the vehicle
    loses 3 frames in cycle 25."""
    vehicle, gcs, companion = Sender(1, 1), Sender(255, 190), Sender(1, 194)
    frames: list[bytes] = []
    for cycle in range(30):
        for k in range(5):
            if cycle == 25 and k == 2:
                vehicle.skip(3)
            frames.append(vehicle.pack(attitude()))
        if cycle == 10:
            companion.skip()
        frames.append(as_id(companion, 194, heartbeat()))
        for k in range(3):
            if cycle == 20 and k == 1:
                companion.skip()
            frames.append(as_id(companion, 220, system_time()))
        frames.append(gcs.pack(heartbeat(gcs=True)))
    path = write_tlog(tmp_path, [(T0 + i * 0.02, f) for i, f in enumerate(frames)])
    lost, found = _links(cli, path, environ)
    assert lost == {"1/1": 3, "1/194": 1, "1/220": 1, "255/190": 0}
    shared = {f["message"].split(":")[0]: f for f in found["seq-shared-counter"]}
    assert set(shared) == {"link 1/194", "link 1/220"}
    # 1/194 jumps over 1/220's 3 numbers in every cycle but the first (29 jumps, one of them over the lost
    # frame too, so not full): 28 full; 1/220 jumps over 1/194's number once a cycle, 29 jumps, all full
    # but cycle 10's (the lost number lies under 1/194's jump, not 1/220's: 1/220's jump is full)
    assert shared["link 1/194"]["message"].startswith("link 1/194: 28 of its 29 jumps")
    assert "(1/220 first)" in shared["link 1/194"]["message"] and "(1 lost in all" in shared["link 1/194"]["message"]
    assert shared["link 1/220"]["message"].startswith("link 1/220: 29 of its 30 jumps")
    assert "seq-gap" not in found


@pytest.mark.parametrize("environ", ENGINES)
def test_an_unrelated_counter_filling_a_vehicles_gaps_hides_nothing(cli: Cli, tmp_path: Path,
                                                                    environ: dict[str, str]) -> None:
    """The vehicle 1/1 loses 20 frames three times; before each loss ends, another id 1/2, on a counter
    of its own that never jumps, sends until its last number is the one just before the vehicle's next (a
    crafted capture: every jump of the vehicle is full). 1/2 skips none of the vehicle's numbers, so the two
    are not one counter: the vehicle's 60 frames stay lost, and seq-gap says so."""
    vehicle, other = Sender(1, 1), Sender(1, 2)
    frames: list[bytes] = []
    for _ in range(3):
        for _ in range(10):
            frames.append(vehicle.pack(attitude()))
        while other.mav.seq != (vehicle.mav.seq + 20) % 256:
            frames.append(other.pack(system_time()))
        vehicle.skip(20)
    frames.append(vehicle.pack(attitude()))
    path = write_tlog(tmp_path, [(T0 + i * 0.02, f) for i, f in enumerate(frames)])
    lost, found = _links(cli, path, environ)
    assert lost == {"1/1": 60, "1/2": 0}
    assert "seq-shared-counter" not in found
    (gap,) = found["seq-gap"]
    assert "link 1/1: 60 frames lost in 3 gap(s)" in gap["message"]


def test_a_late_frame_gives_back_a_number_another_id_used() -> None:
    """SeqTracker by hand: a jump of 4 (3 skipped, the first 2 used by another id), then the skipped
    numbers arrive late: each fills its slot, and the one another id used is no longer counted as shared."""
    tr = SeqTracker()
    tr.feed(10)
    assert tr.feed(14, taken=2, partner=0x0102) == ("gap", 3)
    assert (tr.lost, tr.shared, tr.gap_steps, tr.full_steps) == (3, 2, 1, 0)
    assert tr.feed(11)[0] == "late" and (tr.lost, tr.shared) == (2, 1)
    assert tr.feed(13)[0] == "late" and (tr.lost, tr.shared) == (1, 1)
    assert tr.feed(17, taken=2, partner=0x0102) == ("gap", 2)
    assert (tr.full_steps, tr.partner) == (1, 0x0102)
    assert not tr.counter_shared and tr.missed == tr.lost == 3  # one full step, below SHARED_MIN and no mate
    mate = SeqTracker(full_steps=SHARED_MIN, gap_steps=SHARED_MIN)
    tr.full_steps, tr.mate = SHARED_MIN, mate
    assert tr.counter_shared and tr.missed == tr.lost - tr.shared == 0
