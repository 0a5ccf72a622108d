"""The `param` and `file` events of `mavscope events` (mavscope/analysis/events/records.py) on the bundled
captures, against what the generator sent:

- the truth files it wrote (captures/<capture>.truth.json: the parameter timeline, the objects with their
  bytes' sha256, gaps and parties, the FTP operations with their answer, the script uploads);
- the frames themselves read by pymavlink alone (tests/support/pymavlink_reader.read_pcap: record number and
  time of each frame), for where each set was sent and which frame answered it: the first later
  PARAM_VALUE of that name from the target system (the protocol's answer to PARAM_SET), for PARAM_EXT_SET
  the first PARAM_EXT_ACK that is not PARAM_ACK_IN_PROGRESS (3).
"""

from __future__ import annotations

import importlib
import json
from collections import Counter
from typing import Any

import pytest

from mavscope.analysis.events import EventLog, story
from mavscope.analysis.events.records import FileEvents
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame
from tests.conftest import CAPTURES, Cli
from tests.support.captures import frames
from tests.support.pymavlink_reader import Msg, read_pcap

KEY = ("--key", "passphrase:mavscope-demo")  # the generator signs the GCS's frames with it (captures/README.md)
WIDE = {"COLUMNS": "400"}  # one table row a line
PARAM_ACK_IN_PROGRESS = 3


def truth(capture: str) -> dict[str, Any]:
    return json.loads((CAPTURES / capture.replace(".pcap", ".truth.json")).read_text(encoding="utf-8"))


def _name(m: Msg) -> str:
    v = m.msg.param_id
    return v.decode() if isinstance(v, bytes) else v


def _set_frames(msgs: list[Msg], want: dict[str, Any]) -> tuple[int, float, int | None, float | None]:
    """(record, time) of a truth set's first transmission and of the frame that answered it (or None)."""
    sent = next(m for m in msgs if m.name in ("PARAM_SET", "PARAM_EXT_SET") and list(m.src) == want["from"]
                and _name(m) == want["name"])
    target = want["component"][0]
    if sent.name == "PARAM_EXT_SET":
        answers = [m for m in msgs if m.name == "PARAM_EXT_ACK" and m.msg.param_result != PARAM_ACK_IN_PROGRESS]
    else:
        answers = [m for m in msgs if m.name == "PARAM_VALUE"]
    answer = next((m for m in answers if m.index > sent.index and m.src[0] == target and _name(m) == want["name"]),
                  None)
    assert sent.time is not None
    return sent.index, sent.time, None if answer is None else answer.index, None if answer is None else answer.time


def test_param_events_are_the_truth_timeline(cli: Cli) -> None:
    t = truth("ftp_params.pcap")["params"]["timeline"]
    msgs = read_pcap(CAPTURES / "ftp_params.pcap")
    doc = cli.json("events", CAPTURES / "ftp_params.pcap", "--kind", "param", *KEY)
    got = doc["events"]
    assert [(e["details"]["what"], e["details"]["name"], e["from"], e["details"]["confirmed"], e["details"]["retries"],
             e["details"]["security"], e["details"]["disables"], e["details"]["signature"]) for e in got] == \
        [(w["kind"], w["name"], w["from"], w["confirmed"], w["retries"], w["security"], w["disables"],
          "valid" if w["signed"] else "unsigned") for w in t]
    for e, w in zip(got, t, strict=True):
        d = e["details"]
        assert d["value"] == pytest.approx(w["value"]) and d["previous"] == pytest.approx(w["previous"])
        assert d["reported"] == (None if w["reported"] is None else pytest.approx(w["reported"]))
        if w["kind"] != "set":  # the change: the first PARAM_VALUE carrying the new value
            change = next(m for m in msgs if m.name == "PARAM_VALUE" and _name(m) == w["name"]
                          and m.msg.param_value == w["value"])
            assert (e["frame"], e["to"], d["confirm_frame"]) == (change.index, None, None)
            continue
        frame, sent, answer, answered = _set_frames(msgs, w)
        assert (e["frame"], e["to"], d["confirm_frame"]) == (frame, w["component"], answer)
        if w["confirmed"]:
            assert answered is not None and d["latency_ms"] == pytest.approx((answered - sent) * 1000, abs=0.01)
        if w.get("ack"):
            assert d["ack"] == w["ack"]


def test_cli_lists_each_parameter_set_with_its_answer(cli: Cli) -> None:
    """The table of `mavscope events` names each set of the truth file with its answer (how the generator
    answered it: confirmed, another value reported, nothing), and says which ones are security-relevant."""
    status, out, err = cli("events", CAPTURES / "ftp_params.pcap", *KEY, environ=WIDE)
    assert status == 0, err
    lines = out.splitlines()
    for w in truth("ftp_params.pcap")["params"]["timeline"]:
        if w["kind"] != "set":
            continue
        who, comp = "/".join(map(str, w["from"])), "/".join(map(str, w["component"]))
        head = f"{who} sets {comp} {w['name']} = {w['value']:g} (was {w['previous']:g})"
        (line,) = [x for x in lines if head in x]
        answer = line.split(head, 1)[1]
        if w["retries"]:
            retried = f", retried {w['retries']} time{'s' if w['retries'] > 1 else ''}"
            assert answer.startswith(retried)
            answer = answer.removeprefix(retried)
        if w["confirmed"]:
            assert answer.startswith((": confirmed in", " with PARAM_EXT_SET: confirmed by PARAM_ACK_ACCEPTED in"))
        elif w["confirmed"] is False:
            assert answer.startswith(f": not confirmed: {comp} reports {w['reported']:g}")
        else:
            assert answer.startswith(": not confirmed: no answer in the capture")
        if w["security"]:
            signed = "validly signed" if w["signed"] else "unsigned"
            assert f"security-relevant ({w['security']}, {signed})" in answer
            assert (f"turns off {w['disables']}" in answer) == bool(w["disables"])
        else:
            assert "security-relevant" not in answer


def _objects(events: list[Any]) -> list[Any]:
    return [e for e in events if e.kind == "file" and e.details["what"] == "object"]


@pytest.mark.parametrize("capture", ["ftp_params.pcap", "ftp_lua_upload.pcap", "log_download.pcap"])
def test_file_events_are_the_truth_objects(dialect: Dialect, capture: str) -> None:
    want = truth(capture)
    events = story(frames(capture, dialect), dialect).events
    objects = _objects(events)
    assert [(e.details["object"], e.details["path"], e.details["direction"], list(e.sender), list(e.target),
             e.details["complete"]) for e in objects] == \
        [(o["kind"], o.get("path"), o["direction"], o["sender"], o["receiver"], o["complete"]) for o in want["objects"]]
    for e, o in zip(objects, want["objects"], strict=True):
        d = e.details
        if o["kind"] == "ftp-list":
            assert d["received"] == len(o["entries"]) and f": {len(o['entries'])} entries, complete" in e.text
            continue
        assert (d["size"], d["sha256"], d["gaps"]) == (o["size"], o["sha256"], o["gaps"])
        assert d.get("session") == o.get("session") and d.get("log_id") == o.get("log_id")
        if o["complete"]:
            assert e.text.endswith((f": {o['size']:,} bytes, complete", " announced), complete",
                                    "; a file the vehicle runs as code"))
        else:
            missing = sum(b - a for a, b in o["gaps"])
            assert f"incomplete: {missing:,} bytes missing in {len(o['gaps'])} gap(s)" in e.text
    operations = [e for e in events if e.kind == "file" and e.details["what"] == "operation"]
    assert [(e.details["opcode"], e.details["path"], e.details["result"]) for e in operations] == \
        [(op["opcode"], op["path"], op["result"]) for op in want.get("operations", [])]
    for e, op in zip(operations, want.get("operations", []), strict=True):
        if "crc32" in op:
            assert f"0x{op['crc32']:08x}" in e.text


def test_cli_lists_the_uploaded_lua_script(cli: Cli) -> None:
    t = truth("ftp_lua_upload.pcap")
    (path,) = t["script_uploads"]
    (upload,) = [o for o in t["objects"] if o["kind"] == "ftp-write" and o["path"] == path]
    status, out, err = cli("events", CAPTURES / "ftp_lua_upload.pcap", "--kind", "file", environ=WIDE)
    assert status == 0, err
    who = "/".join(map(str, upload["sender"])) + " -> " + "/".join(map(str, upload["receiver"]))
    (line,) = [x for x in out.splitlines() if f"FTP write {path}" in x]
    assert f"{who} FTP write {path}: {upload['size']:,} bytes, complete; a file the vehicle runs as code" in line
    assert " file " in line  # the kind column
    # the parameters set by the param.pck written over FTP are param events
    doc = cli.json("events", CAPTURES / "ftp_lua_upload.pcap", "--kind", "param")
    assert [(e["details"]["name"], e["details"]["value"], e["details"]["source"], e["details"]["confirmed"])
            for e in doc["events"]] == [(w["name"], w["value"], w["source"], w["confirmed"])
                                        for w in t["params"]["timeline"]]


def test_file_events_release_the_bytes(dialect: Dialect) -> None:
    """Each object is taken from the tracker as it finishes: the tracker keeps no bytes of it (the event
    needs none), before the end and after it."""
    log = EventLog(dialect)
    (source,) = [s for s in log.sources if isinstance(s, FileEvents)]
    finished = 0
    for f in frames("ftp_lua_upload.pcap", dialect):
        log.add(f)
        ctx = source.tracker.ctx
        assert all(r.data == b"" for r in ctx.records) and not ctx.fresh
        finished = len(ctx.records)
    assert finished > 0  # objects finished (a session's TerminateSession, a listing's EOF) before the end
    log.finish()
    assert source.tracker.ctx.budget.held == 0 and all(r.data == b"" for r in source.tracker.ctx.records)


@pytest.mark.parametrize("capture", ["gcs_takeover.pcap", "gps_spoof.pcap"])
def test_no_param_or_file_event_where_none_was_sent(dialect: Dialect, capture: str) -> None:
    """scripts/capgen/incidents.py sends no PARAM_*, FILE_TRANSFER_PROTOCOL, LOG_* or image message."""
    events = story(frames(capture, dialect), dialect).events
    assert [e for e in events if e.kind in ("param", "file")] == []


@pytest.mark.parametrize("capture", ["ftp_params.pcap", "ftp_lua_upload.pcap", "log_download.pcap",
                                     "gcs_takeover.pcap", "commands_ack.pcap"])
def test_each_payload_is_decoded_once(dialect: Dialect, capture: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The log decodes a payload once for every source that wants it, the trackers take those fields: no
    frame is decoded twice in one pass (each module that decodes is watched), and frames with a bad CRC
    are not decoded at all."""
    from mavscope.mavlink import frame as frame_module

    watched = [importlib.import_module(f"mavscope.analysis.{m}") for m in (
        "events.log", "command_log", "mission.reconstruct", "objects.tracker", "params.tracker")]
    decoded: Counter[int] = Counter()

    def counting(f: Frame) -> dict[str, object] | None:
        decoded[f.record] += 1
        return frame_module.decode_payload(f)

    for module in watched:
        monkeypatch.setattr(module, "decode_payload", counting)
    log = EventLog(dialect)
    bad = set()
    for f in frames(capture, dialect):
        log.add(f)
        if f.crc_status is not CrcStatus.OK:
            bad.add(f.record)
    log.finish()
    assert decoded and max(decoded.values()) == 1 and not bad & set(decoded)
