"""`mavscope objects` on the bundled captures made for it, against the truth files the generator wrote
from what it sent (captures/<capture>.truth.json: the files' bytes as SHA-256, the packets it left out)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from tests.conftest import CAPTURES, Cli


def truth(capture: str) -> dict:
    return json.loads((CAPTURES / capture.replace(".pcap", ".truth.json")).read_text())


def check_objects(got: list[dict], want: list[dict]) -> None:
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        assert (g["kind"], g["direction"], g["sender"], g["receiver"]) == (w["kind"], w["direction"], w["sender"],
                                                                           w["receiver"])
        if "path" in w:
            assert g["path"] == w["path"]
        if w["kind"] == "ftp-list":
            assert [(e["type"], e["name"], e["size"]) for e in g["details"]["entries"]] == [
                (e["type"], e["name"], e["size"]) for e in w["entries"]]
            assert g["complete"] is w["complete"]
            continue
        assert (g["size"], g["sha256"], g["complete"], g["gaps"]) == (w["size"], w["sha256"], w["complete"],
                                                                      w["gaps"])
        if "session" in w:
            assert g["details"]["session"] == w["session"]
        if "log_id" in w:
            assert g["details"]["log_id"] == w["log_id"]


@pytest.mark.parametrize("capture", ["ftp_params.pcap", "ftp_lua_upload.pcap", "log_download.pcap"])
def test_objects_match_the_truth(cli: Cli, capture: str) -> None:
    doc = cli.json("objects", CAPTURES / capture)
    check_objects(doc["objects"], truth(capture)["objects"])


def test_the_lua_upload_in_detail(cli: Cli) -> None:
    t = truth("ftp_lua_upload.pcap")
    doc = cli.json("objects", CAPTURES / "ftp_lua_upload.pcap")
    objs = doc["objects"]
    write = next(o for o in objs if o["path"] == "/APM/scripts/fence_helper.lua" and o["kind"] == "ftp-write")
    read = next(o for o in objs if o["path"] == "/APM/scripts/fence_helper.lua" and o["kind"] == "ftp-read")
    want_write = next(o for o in t["objects"] if o["kind"] == "ftp-write")
    want_read = next(o for o in t["objects"] if o["kind"] == "ftp-read")
    assert write["details"]["rewrites"] == want_write["rewritten_blocks"]  # the write sent again
    assert read["details"]["retried_requests"] == want_read["retried_bursts"]  # the burst asked for again
    assert read["sha256"] == write["sha256"]  # read back what was written
    ops = [{"opcode": o["opcode"], "path": o["path"], "result": o["result"]} for o in doc["operations"]]
    assert ops == [{k: o[k] for k in ("opcode", "path", "result")} for o in t["operations"]]
    crc = next(o for o in doc["operations"] if o["opcode"] == "CalcFileCRC32")
    assert crc["detail"] == f"CRC-32 0x{t['operations'][0]['crc32']:08x}"
    findings = {f["code"]: f for f in doc["findings"]}
    assert set(findings) == {"ftp-upload", "script-upload", "object-unsafe-path"}
    assert all(p in findings["script-upload"]["message"] for p in t["script_uploads"])
    assert all(repr(p) in findings["object-unsafe-path"]["message"] for p in t["unsafe_paths"])


def test_out_writes_each_object_and_the_manifest(cli: Cli, tmp_path: Path) -> None:
    out = tmp_path / "objects"
    status, text, err = cli("objects", CAPTURES / "ftp_lua_upload.pcap", "--out", out)
    assert status == 0, err
    manifest = json.loads((out / "manifest.json").read_text())
    want = truth("ftp_lua_upload.pcap")["objects"]
    assert sorted(p.name for p in out.iterdir()) == sorted([o["file"] for o in manifest["objects"]] +
                                                           ["manifest.json"])
    for o, w in zip(manifest["objects"], want, strict=True):
        data = (out / o["file"]).read_bytes()
        assert hashlib.sha256(data).hexdigest() == o["sha256"] and len(data) == o["size"]
        if "sha256" in w:
            assert o["sha256"] == w["sha256"]
        assert {"path", "file", "direction", "size", "sha256", "complete", "gaps", "frames", "sender", "receiver",
                "signatures"} <= set(o)
    lua = next(o for o in manifest["objects"] if o["kind"] == "ftp-write" and o["path"].endswith(".lua"))
    assert lua["file"] == "0002-APM_scripts_fence_helper.lua"
    # 1223 bytes in 7 blocks of 200: the GCS sends CreateFile, 7 writes, one again, TerminateSession; the
    # vehicle answers each (the ACK that was lost is not in the capture)
    assert lua["signatures"] == {"1/1": {"unsigned": 9}, "255/230": {"unsigned": 10}}
    assert "fence_helper.lua" in text and "Written to" in text
    # a second run into the same directory replaces the files
    status, _, err = cli("objects", CAPTURES / "ftp_lua_upload.pcap", "--out", out)
    assert status == 0, err and len(list(out.iterdir())) == len(manifest["objects"]) + 1


def test_out_never_writes_through_a_planted_symlink(cli: Cli, tmp_path: Path) -> None:
    out = tmp_path / "objects"
    out.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    (out / "0002-APM_scripts_fence_helper.lua").symlink_to(victim)
    (out / "manifest.json").symlink_to(victim)
    status, _, err = cli("objects", CAPTURES / "ftp_lua_upload.pcap", "--out", out)
    assert status == 0, err
    assert victim.read_text() == "keep me"
    assert not (out / "manifest.json").is_symlink() and not (out / "0002-APM_scripts_fence_helper.lua").is_symlink()


def test_log_download_frames_and_selection(cli: Cli) -> None:
    t = truth("log_download.pcap")["objects"]
    doc = cli.json("objects", CAPTURES / "log_download.pcap")
    complete = doc["objects"][0]
    assert complete["details"]["log_id"] == 2 and complete["details"]["requests"] == 3  # one request, two again
    assert complete["announced_size"] == t[0]["size"]  # LOG_ENTRY's size
    first = complete["first_frame"]
    # -Y keeps the objects with a frame the filter matches: log 1's request only
    doc = cli.json("objects", CAPTURES / "log_download.pcap", "-Y", "LOG_REQUEST_DATA.id == 1")
    assert [o["details"]["log_id"] for o in doc["objects"]] == [1]
    assert first > 0
