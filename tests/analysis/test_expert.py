"""Expert findings on captures with known events, and on flows built here with pymavlink."""

from __future__ import annotations

from pathlib import Path

from mavscope.analysis.expert import DETECTORS, KeyLeaks, expert_findings
from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.conftest import Cli
from tests.support import flows
from tests.support.captures import frames, truth


def codes(findings) -> dict[str, list]:  # type: ignore[no-untyped-def]
    out: dict[str, list] = {}
    for f in findings:
        out.setdefault(f.code, []).append(f)
    return out


def test_commands_capture(dialect: Dialect) -> None:
    t = truth("commands_ack.pcap")
    found = codes(expert_findings(frames("commands_ack.pcap", dialect), dialect))
    (leak,) = found["key-leak"]
    assert leak.severity.value == "error" and leak.frames == (t["setup_signing_record"],)
    (replay,) = found["replayed-command"]
    assert replay.frames == (t["commands"][-1]["replay_of_record"], t["replay_record"])
    (new,) = found["new-commander"]
    assert "66/190" in new.message
    assert "seq-gap" not in found and "bad-crc-burst" not in found


def test_loss_capture(dialect: Dialect) -> None:
    found = codes(expert_findings(frames("stats_loss.pcap", dialect), dialect))
    (burst,) = found["bad-crc-burst"]
    assert len(burst.frames) == truth("stats_loss.pcap")["links"]["1/1"]["crc_bad"]
    (gap,) = found["seq-gap"]
    # the generator removed a run of 40 vehicle frames and 4 single ones (captures/README.md): 44 in all
    assert "40 frames lost in 1 gap" in gap.message and "44 lost in all" in gap.message
    assert len(found["seq-duplicate"]) == 1


def test_clean_captures_have_no_findings(dialect: Dialect) -> None:
    for name in ("px4_sitl_udp.pcap", "mission_resend.pcap", "clock_skew.pcap"):
        assert expert_findings(frames(name, dialect), dialect) == [], name


def test_detectors_are_an_open_list(dialect: Dialect) -> None:
    fs = frames("commands_ack.pcap", dialect)
    assert KeyLeaks in DETECTORS
    assert [f.code for f in expert_findings(fs, dialect, [KeyLeaks])] == ["key-leak"]


def _findings(cli: Cli, path: str) -> dict[str, list[dict]]:
    doc = cli.json("stats", path)
    out: dict[str, list[dict]] = {}
    for f in doc["findings"]:
        out.setdefault(f["code"], []).append(f)
    return out


def _gcs_flow(lose: set[int] = frozenset(), frames_: int = 700) -> list[tuple[float, bytes]]:  # type: ignore[assignment]
    """A GCS (255/190) sending a neutral-stick MANUAL_CONTROL at 20 Hz and a HEARTBEAT every 20th frame:
    after 256 frames the counter wraps and the same MANUAL_CONTROL bytes come back, in sequence."""
    gcs = flows.Sender(255, 190)
    out = []
    for i in range(frames_):
        msg = flows.heartbeat(gcs=True) if i % 20 == 0 else flows.manual_control()
        frame = gcs.pack(msg)
        if i not in lose:
            out.append((flows.T0 + i * 0.05, frame))
    return out


def test_manual_control_repeating_after_the_wrap_is_not_a_replay(cli: Cli, tmp_path: Path) -> None:
    found = _findings(cli, flows.write_tlog(tmp_path, _gcs_flow()))
    assert "replayed-command" not in found and "seq-gap" not in found


def test_wrap_repeats_with_loss_are_not_replays(cli: Cli, tmp_path: Path) -> None:
    # 30 frames lost in one run and 5 single ones: copies still come after whole counter cycles
    lose = set(range(300, 330)) | {50, 260, 400, 512, 640}
    found = _findings(cli, flows.write_tlog(tmp_path, _gcs_flow(lose)))
    assert "replayed-command" not in found
    # a ground station's own frames in a tlog: its 35 missing numbers are said, not warned as link loss
    assert "seq-gap" not in found
    (part,) = found["seq-logged-in-part"]
    assert part["severity"] == "note" and "35 numbers missing" in part["message"]
    # the same frames captured on the wire (UDP): lost on the link
    pcap = flows.write_udp_pcap(tmp_path / "flow.pcap", [(("10.0.0.2", 14550), ("10.0.0.1", 14555), frame)
                                                         for _, frame in _gcs_flow(lose)])
    found = _findings(cli, str(pcap))
    assert "replayed-command" not in found and "seq-logged-in-part" not in found
    (gap,) = found["seq-gap"]
    assert "30 frames lost in 1 gap" in gap["message"] and "35 lost in all" in gap["message"]


def test_a_copy_within_the_counter_cycle_is_a_replay(cli: Cli, tmp_path: Path) -> None:
    """An arm command copied byte for byte and sent again 5 frames later, out of the sender's sequence."""
    gcs = flows.Sender(255, 190)
    entries = [(flows.T0 + i * 0.05, gcs.pack(flows.heartbeat(gcs=True))) for i in range(10)]
    arm = gcs.pack(flows.command_long(400, 1.0))
    entries.append((flows.T0 + 0.5, arm))
    entries += [(flows.T0 + 0.55 + i * 0.05, gcs.pack(flows.heartbeat(gcs=True))) for i in range(5)]
    entries.append((flows.T0 + 0.9, arm))  # the replay: record 17
    entries += [(flows.T0 + 1.0 + i * 0.05, gcs.pack(flows.heartbeat(gcs=True))) for i in range(5)]
    found = _findings(cli, flows.write_tlog(tmp_path, entries))
    (replay,) = found["replayed-command"]
    assert replay["frames"] == [11, 17] and "COMMAND_LONG 1" in replay["message"]


def test_a_second_counter_is_interleaving_not_loss(cli: Cli, tmp_path: Path) -> None:
    """Mission Planner's pattern: the main counter, and REQUEST_DATA_STREAM on a counter of its own."""
    main, streams = flows.Sender(255, 190, seq=0), flows.Sender(255, 190, seq=98)
    entries = []
    for i in range(400):
        t = flows.T0 + i * 0.05
        entries.append((t, main.pack(flows.heartbeat(gcs=True) if i % 10 == 0 else flows.manual_control(x=i))))
        if i % 40 == 5:
            entries.append((t + 0.01, streams.pack(
                flows.v2.MAVLink_request_data_stream_message(1, 1, 0, 4, 1))))
    path = flows.write_tlog(tmp_path, entries)
    doc = cli.json("stats", path)
    (link,) = [lk for lk in doc["links"] if (lk["sysid"], lk["compid"]) == (255, 190)]
    assert link["lost"] == 0  # every frame of both counters is in the file
    found = {f["code"] for f in doc["findings"]}
    assert "seq-gap" not in found and "replayed-command" not in found


def _bursts(tmp_path: Path, second: list[object]) -> tuple[str, list[int]]:
    """A GCS (255/190): 120 HEARTBEATs and MANUAL_CONTROLs on its main counter and, after every 20th of them
    from the 10th, the messages of `second` numbered 1, 2, 3... (a counter that starts over each time, as
    the real GCS tlogs number REQUEST_DATA_STREAM: tests/crosscheck/test_real_findings.py). The main counter
    is 3 to 110 ahead of them (behind by less than 128: SeqTracker's window): each of those frames steps
    back, filling no gap. Returns the tlog and the record numbers of the second counter's frames."""
    main = flows.Sender(255, 190)
    entries: list[tuple[float, bytes]] = []
    records = []
    for i in range(120):
        t = flows.T0 + i * 0.05
        entries.append((t, main.pack(flows.heartbeat(gcs=True) if i % 10 == 0 else flows.manual_control(x=i))))
        if i % 20 == 10:
            burst = flows.Sender(255, 190, seq=1)
            for k, msg in enumerate(second):
                entries.append((t + 0.001 * (k + 1), burst.pack(msg)))
                records.append(len(entries))
    return flows.write_tlog(tmp_path, entries), records


def _both_paths(cli: Cli, path: str) -> dict[str, list[dict]]:
    """The findings of `stats`, the same from the native engine and the pure-Python path."""
    native = cli.json("stats", path)["findings"]
    assert cli.json("stats", path, environ={"MAVSCOPE_PURE": "1"})["findings"] == native
    out: dict[str, list[dict]] = {}
    for f in native:
        if f["message"].startswith("link 255/190"):
            out.setdefault(f["code"], []).append(f)
    return out


STREAMS = [flows.v2.MAVLink_request_data_stream_message(1, 1, k, 4, 1) for k in range(1, 8)]


def test_request_data_stream_on_a_counter_of_its_own_is_one_note(cli: Cli, tmp_path: Path) -> None:
    """Mission Planner's and QGroundControl's pattern: 6 bursts of 7 REQUEST_DATA_STREAMs numbered 1..7."""
    path, records = _bursts(tmp_path, STREAMS)
    found = _both_paths(cli, path)
    assert set(found) == {"seq-own-counter"}  # no seq-duplicate, seq-reordered, seq-interleaved
    (own,) = found["seq-own-counter"]
    assert own["severity"] == "note" and own["frames"] == records[:len(own["frames"])]
    assert "42 frames out of sequence, all REQUEST_DATA_STREAM (42 repeat a number already seen, 0 fill" \
           in own["message"]


def test_commands_on_a_second_counter_stay_two_counters(cli: Cli, tmp_path: Path) -> None:
    """The same pattern with COMMAND_LONGs, HEARTBEATs, or REQUEST_DATA_STREAMs but for one HEARTBEAT: another
    sender under the GCS's id until shown otherwise (an injector keeping its own counter), a warning."""
    commands = [flows.command_long(400, float(k % 2)) for k in range(7)]
    for second, named in ((commands, "(all COMMAND_LONG)"), ([flows.heartbeat(gcs=True)] * 7, "(all HEARTBEAT)"),
                          (STREAMS[:6] + [flows.heartbeat(gcs=True)], "(REQUEST_DATA_STREAM, HEARTBEAT)")):
        sub = tmp_path / named.strip("()").replace(", ", "-").replace(" ", "_")
        sub.mkdir()
        found = _both_paths(cli, _bursts(sub, second)[0])
        assert "seq-own-counter" not in found, named
        (two,) = found["seq-interleaved"]
        assert two["severity"] == "warn" and "42 of 162 frames step back" in two["message"], two["message"]
        assert two["message"].endswith(named), two["message"]
        assert found["seq-duplicate"][0]["message"].endswith(named)


def test_new_commanders_of_a_vehicle_are_one_finding(dialect: Dialect, tmp_path: Path) -> None:
    """Built here: vehicle 1 (HEARTBEAT), commanded first by 255/190; then 254/190 (twice), 253/1, 255/191
    (the first commander's system: not new), vehicle 1 itself (not a command to another), and 250/1 to a
    ground station (HEARTBEAT type GCS: not about a vehicle). New commanders of vehicle 1: 254/190 and
    253/1, first in records 4 and 6 (records count tlog entries from 1). Vehicle 2 has one new commander,
    252/1 in record 10, named in the sentence of a single commander."""
    from tests.support.flows import T0, Sender, command_long, heartbeat, write_tlog

    vehicle, gcs = Sender(1, 1), Sender(249, 190)
    s = {k: Sender(*k) for k in ((255, 190), (254, 190), (253, 1), (255, 191), (250, 1), (252, 1))}
    entries = [vehicle.pack(heartbeat()), gcs.pack(heartbeat(gcs=True)),           # 1, 2
               s[(255, 190)].pack(command_long()), s[(254, 190)].pack(command_long()),  # 3, 4
               s[(254, 190)].pack(command_long()), s[(253, 1)].pack(command_long()),    # 5, 6
               s[(255, 191)].pack(command_long()), vehicle.pack(command_long()),        # 7, 8
               s[(255, 190)].pack(command_long(target=2)), s[(252, 1)].pack(command_long(target=2)),  # 9, 10
               s[(250, 1)].pack(command_long(target=249)), s[(255, 190)].pack(command_long(target=249))]  # 11, 12
    path = write_tlog(tmp_path, [(T0 + i * 0.1, f) for i, f in enumerate(entries)])
    with open_capture(path) as r:
        fs = [f for f in Dissector(dialect).run(r) if type(f) is not Anomaly]
    found = codes(expert_findings(fs, dialect))
    one, two = sorted(found["new-commander"], key=lambda f: f.frames)
    assert one.frames == (4, 6)
    assert one.message == ("2 senders command system 1 after 255/190, which commanded it first: 254/190 "
                           "(COMMAND_LONG), 253/1 (COMMAND_LONG)")
    assert two.frames == (10,)
    assert two.message == "system 252/1 commands system 2 (COMMAND_LONG), which 255/190 commanded until then"
