"""Bad CRCs from another definition of a message (issue 35, item 14): a dialect mismatch, not line noise.

The frames are built by pymavlink: a MatrixPilot vehicle's FLEXIFUNCTION_SET (id 150, CRC_EXTRA 181 in
pymavlink's matrixpilot dialect), which mavscope's default dialect (all.xml) defines as SENSOR_OFFSETS
(CRC_EXTRA 134); and frames whose CRC the test computes with a CRC_EXTRA it chooses (pymavlink's x25crc
over header and payload, then that byte). Every such frame fails mavscope's check; all of one sender and id
fit the other CRC_EXTRA, so `dialect-mismatch` names the id, the sender, the count and that CRC_EXTRA, and
no `bad-crc-burst` counts them. Real line noise stays noise. Both engines say the same (test_replays.both).
"""

from __future__ import annotations

import struct
from pathlib import Path

from pymavlink.dialects.v20 import all as v2
from pymavlink.dialects.v20 import matrixpilot

from mavscope.analysis.crcextra import MISMATCH_MIN
from tests.analysis.test_replays import both
from tests.conftest import Cli
from tests.support import flows


def with_extra(frame: bytes, extra: int) -> bytes:
    """A v2 frame with its CRC computed with CRC_EXTRA `extra` (unsigned)."""
    length = frame[1]
    crc = v2.x25crc(frame[1:10 + length])
    crc.accumulate(bytes([extra]))
    return frame[:10 + length] + struct.pack("<H", crc.crc)


def matrixpilot_flow(n: int) -> list[tuple[float, bytes]]:
    """A vehicle 1/1: HEARTBEATs (all.xml's) and, between them, n FLEXIFUNCTION_SETs at 10 Hz."""
    vehicle = flows.Sender(1, 1)
    mp = matrixpilot.MAVLink(None, srcSystem=1, srcComponent=1)
    out = []
    for i in range(n):
        if i % 10 == 0:
            out.append((flows.T0 + i * 0.1, vehicle.pack(flows.heartbeat())))
        mp.seq = vehicle.mav.seq
        out.append((flows.T0 + i * 0.1 + 0.01, bytes(mp.flexifunction_set_encode(255, 190).pack(mp))))
        vehicle.skip()
    return out


def test_another_dialects_definition_is_named(cli: Cli, tmp_path: Path) -> None:
    found = both(cli, flows.write_tlog(tmp_path, matrixpilot_flow(200)))
    assert "bad-crc-burst" not in found
    (m,) = found["dialect-mismatch"]
    text = m["message"]
    assert "200 frame(s) of message id 150 from 1/1" in text and "CRC_EXTRA 134 (SENSOR_OFFSETS" in text
    assert "fits CRC_EXTRA 181" in text and "FLEXIFUNCTION_SET (id 150, matrixpilot.xml)" in text
    assert len(m["frames"]) == 50 and m["frames"][0] == 2  # the first FLEXIFUNCTION_SET is record 2


def test_a_chosen_crc_extra_beside_real_noise(cli: Cli, tmp_path: Path) -> None:
    """791 ATTITUDE frames (id 30) of 1/1 with CRC_EXTRA 77 (all.xml's is 39), and a burst of 4 frames
    damaged on the line (a payload byte flipped after the CRC was computed: they fit no CRC_EXTRA, or a
    random one each) in the middle: the mismatch is said, the 4 damaged frames are the one burst."""
    vehicle = flows.Sender(1, 1)
    entries: list[tuple[float, bytes]] = []
    damaged = []
    for i in range(791):
        t = flows.T0 + i * 0.02
        frame = vehicle.pack(v2.MAVLink_attitude_message(i, 0.1, 0.2, 0.3, 0, 0, 0))
        entries.append((t, with_extra(frame, 77)))
        if i in (400, 401, 402, 403):
            hb = bytearray(vehicle.pack(flows.heartbeat()))
            hb[12] ^= 0x5A
            entries.append((t + 0.001, bytes(hb)))
            damaged.append(len(entries))
    found = both(cli, flows.write_tlog(tmp_path, entries))
    (m,) = found["dialect-mismatch"]
    assert "791 frame(s) of message id 30 from 1/1" in m["message"] and "fits CRC_EXTRA 77" in m["message"]
    assert "CRC_EXTRA 39 (ATTITUDE" in m["message"]
    (burst,) = found["bad-crc-burst"]
    assert burst["frames"] == damaged and burst["message"].startswith("4 frames with a bad CRC")


def test_a_few_frames_are_not_a_mismatch(cli: Cli, tmp_path: Path) -> None:
    """Fewer than MISMATCH_MIN such frames in a row: a burst of bad CRCs, as before."""
    found = both(cli, flows.write_tlog(tmp_path, matrixpilot_flow(MISMATCH_MIN - 1)))
    assert "dialect-mismatch" not in found
    assert found["bad-crc-burst"][0]["message"].startswith(f"{MISMATCH_MIN - 1} frames with a bad CRC")


def test_line_noise_is_noise(cli: Cli, real_captures: Path) -> None:
    """The 42 bad-CRC frames pymavlink's parser finds in a real corrupted serial stream, each tried with all 256
    CRC_EXTRA bytes (pymavlink's x25crc): one fits a byte by chance (1 in 256 does), no two of one sender and
    id fit the same byte, so no definition explains them, and mavscope says no mismatch."""
    path = real_captures / "ap_hw_copter_cubeorange_raw_serial_corrupt_adsb_v1.raw"
    mav = v2.MAVLink(None)
    mav.robust_parsing = True
    data = path.read_bytes()
    bad = []
    for i in range(0, len(data), 4096):
        for m in mav.parse_buffer(data[i:i + 4096]) or []:
            if m.get_type() == "BAD_DATA" and "CRC" in str(getattr(m, "reason", "")):
                bad.append(bytes(m.get_msgbuf()))
    assert len(bad) == 42
    groups: dict[tuple[bytes, int, int], int] = {}
    for raw in bad:
        h = 10 if raw[0] == 0xFD else 6
        msgid = raw[7] | raw[8] << 8 | raw[9] << 16 if h == 10 else raw[5]
        crc = raw[h + raw[1]] | raw[h + raw[1] + 1] << 8
        fits = []
        for b in range(256):
            x = v2.x25crc(raw[1:h + raw[1]])
            x.accumulate(bytes([b]))
            if x.crc == crc:
                fits.append(b)
        for b in fits:
            key = (raw[h - 5:h - 3] if h == 10 else raw[3:5], msgid, b)
            groups[key] = groups.get(key, 0) + 1
    assert sum(groups.values()) <= 2 and max(groups.values(), default=0) == 1
    doc = cli.json("stats", str(path))
    assert "dialect-mismatch" not in {f["code"] for f in doc["findings"]}
