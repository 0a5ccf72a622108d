"""`mavscope objects` on real captures, against answers derived independently of mavscope: READS and the
numbers below are written out for reading, and `test_written_out_answers_are_the_derivation` derives
them again from pymavlink's messages by the protocols' rules (tests/support/real_truth.py: `ftp_reads`,
`images`; no mavscope import):

- ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog: three gapless FTP reads of @PARAM/param.pck from
  ArduPlane 1/1, each ending exactly at the EOF NAK offset; Mission Planner's first open NAKed
  InvalidSession. Frame numbers are tlog records (the derivation's 0-based index + 1; this tlog holds no
  text).
- px4flow_v1_encapsulated_data.tlog: 177 DATA_TRANSMISSION_HANDSHAKE, each opening an image of 4096 bytes
  in 17 packets of 253; 175 complete, 2 not (the first misses packets 5-11 and holds 2 duplicates, the
  last misses 9-16); 14 ENCAPSULATED_DATA before the first handshake. The SHA-256 of the images
  (zero-filled where packets are missing), in order, joined with spaces, hash to IMAGES_DIGEST.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from tests.conftest import Cli

PLANE = "ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog"
PX4FLOW = "px4flow_v1_encapsulated_data.tlog"
# (requester, path, session, announced size, length, sha256, OpenFileRO frame, data ACKs)
READS = [
    ([255, 230], "@PARAM/param.pck?withdefaults=1", 1, 17100, 16169,
     "0a50b2aa1e5edffb61853ac593b36ba63082f1b9b1cce2ed6566545d36d3ab94", 64, 203),
    ([255, 230], "@PARAM/param.pck?withdefaults=1", 3, 17220, 16169,
     "a468298ac036fc60ff4fb8311a429d43998bfe0850f0b70849bc6a6c403a23c7", 435, 203),
    ([255, 190], "@PARAM/param.pck", 0, 17220, 15926,
     "f8dd64b88d3f80ef908a5aca7442fe2d175816d060216709a8970beb47f55b94", 2446, 67),
]
IMAGES_DIGEST = "f1f33f0c3baef60ebadc235af4a7e205c165b986463599385849b58e7cff3e8d"


def capture(real_captures: Path, name: str) -> Path:
    path = real_captures / name
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    return path


def test_plane_param_reads(cli: Cli, real_captures: Path, tmp_path: Path) -> None:
    doc = cli.json("objects", capture(real_captures, PLANE), "--out", tmp_path)
    got = [(o["receiver"], o["path"], o["details"]["session"], o["announced_size"], o["size"], o["sha256"],
            o["first_frame"], o["details"]["data_packets"]) for o in doc["objects"]]
    assert got == READS
    assert all(o["complete"] and o["gaps"] == [] and o["sender"] == [1, 1] for o in doc["objects"])
    assert all(o["details"]["eof_offset"] == o["size"] for o in doc["objects"])
    for o in doc["objects"]:
        assert hashlib.sha256((tmp_path / o["file"]).read_bytes()).hexdigest() == o["sha256"]
    assert [(op["opcode"], op["path"], op["client"], op["result"]) for op in doc["operations"]] == [
        ("OpenFileRO", "@PARAM/param.pck", [255, 190], "NAK InvalidSession")]
    assert doc["findings"] == []


def test_px4flow_images(cli: Cli, real_captures: Path) -> None:
    doc = cli.json("objects", capture(real_captures, PX4FLOW))
    images = doc["objects"]
    assert len(images) == 177 and sum(o["complete"] for o in images) == 175
    assert hashlib.sha256(" ".join(o["sha256"] for o in images).encode()).hexdigest() == IMAGES_DIGEST
    assert all((o["size"], o["details"]["packets"], o["details"]["payload"], o["details"]["width"]) ==
               (4096, 17, 253, 64) for o in images)
    first, last = images[0], images[-1]
    assert (first["details"]["missing_packets"], first["details"]["duplicate_packets"]) == ([[5, 11]], 2)
    assert (last["details"]["missing_packets"], last["details"]["duplicate_packets"]) == ([[9, 16]], 0)
    assert doc["image_orphans"]["frames"] == 14
    assert all(o["sender"] == [81, 50] for o in images)


def test_written_out_answers_are_the_derivation(real_captures: Path) -> None:
    from tests.support.pymavlink_reader import read
    from tests.support.real_truth import ftp_reads, images

    reads = ftp_reads(read(capture(real_captures, PLANE)))
    opened = [r for r in reads if "session" in r]
    assert [(list(r["client"]), r["path"], r["session"], r["announced_size"], r["length"], r["sha256"],
             r["open_index"] + 1, r["data_acks"]) for r in opened] == READS
    assert all(r["gaps"] == [] and r["eof_nak"] is not None for r in opened)
    assert [(r["path"], r["client"], r["open_nak"]) for r in reads if "open_nak" in r] == [
        ("@PARAM/param.pck", (255, 190), "InvalidSession")]

    got = images(read(capture(real_captures, PX4FLOW)))
    imgs = got["images"]
    assert hashlib.sha256(" ".join(i["sha256"] for i in imgs).encode()).hexdigest() == IMAGES_DIGEST
    assert len(imgs) == 177 and sum(not i["missing"] for i in imgs) == 175 and got["orphans"] == 14
    assert {(i["size"], i["packets"], i["payload"], i["width"], i["sender"]) for i in imgs} == {
        (4096, 17, 253, 64, (81, 50))}
    assert (imgs[0]["missing"], imgs[0]["duplicates"]) == (list(range(5, 12)), 2)
    assert (imgs[-1]["missing"], imgs[-1]["duplicates"]) == (list(range(9, 17)), 0)
