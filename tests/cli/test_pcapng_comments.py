"""`read -w OUT.pcapng`: each packet written carries its frames' verdicts and notes as pcapng comments.

A capture built here (tests/support): a signed HEARTBEAT of 1/1 (valid with its key), an unsigned ATTITUDE
of 1/1 (unsigned in a signed stream: the security stage's note), an ATTITUDE of 1/1 whose CRC is changed
(bad CRC, and unsigned too), and a datagram of two frames of 2/1 (two comments on one packet). The
expected comments are written out here from those frames (frame_comment's form). They are read back two
ways: by walking the pcapng blocks by hand (the opt_comment options of each Enhanced Packet Block, pcapng
spec section 4.3) and, where it is installed, by tshark (`-T fields -e frame.comment`), which shows a
packet's comments joined by commas. A pcap has no comments: `-w OUT.pcap` is unchanged.
"""

from __future__ import annotations

import shutil
import struct
import subprocess
from pathlib import Path

from tests.conftest import Cli
from tests.native.test_bad_crc_native import _attitude, _bad, _crc
from tests.support.builders import write_udp_pcap
from tests.support.security import SHA_KEY, heartbeat, signer

GCS, VEHICLE = ("10.0.0.1", 14550), ("10.0.0.2", 14580)
SIGNS = "from 1/1, which sends signed frames"


def _capture(tmp: Path) -> tuple[Path, list[list[str]]]:
    s, v, other = signer(SHA_KEY, 1, 1), signer(None, 1, 1), signer(None, 2, 1)
    bad = _bad(_attitude(v, 0.3))
    path = write_udp_pcap(tmp / "c.pcap", [(VEHICLE, GCS, heartbeat(s)), (VEHICLE, GCS, _attitude(v)),
                                           (VEHICLE, GCS, bad), (VEHICLE, GCS, _attitude(other) + _attitude(other))])
    want = [
        ["mavscope: frame 1 HEARTBEAT from 1/1: CRC ok; signature valid (first frame of its stream"],
        [f"mavscope: frame 2 ATTITUDE from 1/1: CRC ok; note warn unsigned-in-signed-stream: unsigned ATTITUDE "
         f"{SIGNS}"],
        [f"mavscope: frame 3 ATTITUDE from 1/1: CRC bad; note error bad-crc: CRC 0x{_crc(bad)} does not match the "
         f"frame; note warn unsigned-in-signed-stream: unsigned ATTITUDE {SIGNS}"],
        ["mavscope: frame 4 ATTITUDE from 2/1: CRC ok", "mavscope: frame 4.2 ATTITUDE from 2/1: CRC ok"],
    ]
    return path, want


def _comments(data: bytes) -> list[list[str]]:
    """The opt_comment values of each Enhanced Packet Block, in order (little-endian pcapng)."""
    out, pos = [], 0
    while pos + 12 <= len(data):
        btype, blen = struct.unpack_from("<II", data, pos)
        if btype == 6:
            caplen = struct.unpack_from("<I", data, pos + 20)[0]
            opt, mine = pos + 28 + caplen + (-caplen & 3), []
            while opt + 4 <= pos + blen - 4:
                code, length = struct.unpack_from("<HH", data, opt)
                if code == 0:
                    break
                if code == 1:
                    mine.append(data[opt + 4:opt + 4 + length].decode("utf-8"))
                opt += 4 + length + (-length & 3)
            out.append(mine)
        pos += blen
    return out


def test_verdicts_as_packet_comments(cli: Cli, tmp_path: Path) -> None:
    path, want = _capture(tmp_path)
    out = tmp_path / "out.pcapng"
    got = cli("read", str(path), "-w", str(out), "-q", "--key", "hex:" + SHA_KEY.hex())
    assert got.status == 0, got.err
    comments = _comments(out.read_bytes())
    assert len(comments) == 4
    assert comments[0][0].startswith(want[0][0]) and len(comments[0]) == 1  # (the reason's numbers follow)
    assert comments[1:] == want[1:]
    if shutil.which("tshark"):
        ref = subprocess.run(["tshark", "-r", str(out), "-T", "fields", "-e", "frame.comment"], capture_output=True,
                             text=True, timeout=120, check=False)
        assert ref.returncode == 0, ref.stderr
        assert ref.stdout.splitlines()[1:] == [",".join(c) for c in want[1:]]


def test_only_shown_frames_and_no_comment_in_a_pcap(cli: Cli, tmp_path: Path) -> None:
    path, want = _capture(tmp_path)
    out = tmp_path / "out.pcapng"
    assert cli("read", str(path), "-Y", "mavlink.sysid == 2", "-w", str(out), "-q").status == 0
    assert _comments(out.read_bytes()) == [want[3]]
    plain = tmp_path / "out.pcap"
    assert cli("read", str(path), "-w", str(plain), "-q").status == 0
    assert plain.read_bytes()[:4] == b"\xd4\xc3\xb2\xa1" and b"mavscope:" not in plain.read_bytes()
