"""Replays (issue 35, item 12): a copy byte for byte is a replay only where it is out of place.

The flows are built here with pymavlink (tests/support/flows.py); each test says what it built and so
what a replay is in it, by the definition in docs/analysis.md ("Replays"): a frame repeating an earlier
one byte for byte (sequence number, payload and, signed, the signature timestamp) that is out of place
in its sender's sequence (the sender's counter runs on from before it, or reaches its number again), or
signed with a timestamp that did not advance. A periodic stream repeating its neutral value each time
the 8-bit counter comes round is in its place. Both engines must say the same (stats, stats --json,
audit, audit --json: stdout, stderr, exit status), and audit must show every security finding stats has.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import Cli
from tests.native.engines import PURE
from tests.support import flows
from tests.support.pymavlink_reader import read as pymavlink_read
from tests.support.security import command_long, signer

GCS = (255, 190)
COMMANDING = {"COMMAND_LONG", "COMMAND_INT", "SET_MODE", "MISSION_COUNT", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT",
              "MISSION_ITEM", "MISSION_ITEM_INT", "PARAM_SET", "PARAM_EXT_SET", "SET_POSITION_TARGET_LOCAL_NED",
              "SET_POSITION_TARGET_GLOBAL_INT", "SET_ATTITUDE_TARGET", "MANUAL_CONTROL", "RC_CHANNELS_OVERRIDE",
              "SETUP_SIGNING", "SET_HOME_POSITION", "SET_GPS_GLOBAL_ORIGIN", "FILE_TRANSFER_PROTOCOL"}


def both(cli: Cli, path: str, *extra: str) -> dict[str, list[dict]]:
    """stats, audit and verify, text and JSON, on both engines (equal), and audit holding every security
    finding of stats: stats' findings by code."""
    for command in ("stats", "audit"):
        for fmt in ((), ("--json",)):
            pure = cli(command, path, *fmt, *extra, environ=PURE)
            native = cli(command, path, *fmt, *extra, environ={})
            assert (native.out, native.err, native.status) == (pure.out, pure.err, pure.status), (command, fmt)
    for fmt in ((), ("--json",)):  # verify needs a key: any (these captures' signed frames then fail it)
        pure = cli("verify", path, "--key", "passphrase:x", *fmt, *extra, environ=PURE)
        native = cli("verify", path, "--key", "passphrase:x", *fmt, *extra, environ={})
        assert (native.out, native.err, native.status) == (pure.out, pure.err, pure.status), ("verify", fmt)
    stats = cli.json("stats", path, *extra)
    audit = cli("audit", path, "--json", *extra)
    import json

    audited = [(f["code"], f["message"], f["frames"]) for f in json.loads(audit.out)["findings"]]
    from mavscope.notes import CODES, Group

    for f in stats["findings"]:
        if CODES[f["code"]].group is Group.SECURITY:
            assert (f["code"], f["message"], f["frames"]) in audited, f["code"]
    out: dict[str, list[dict]] = {}
    for f in stats["findings"]:
        out.setdefault(f["code"], []).append(f)
    return out


def neutral_stream(n: int, lose: set[int] = frozenset(), swap: set[int] = frozenset()) -> list[tuple[float, bytes]]:  # type: ignore[assignment]
    """A GCS sending a neutral-stick MANUAL_CONTROL at 20 Hz and a HEARTBEAT every 20th frame: frame i has
    sequence number i % 256, so frames i and i + 256 are the same bytes. `lose`: frames never captured;
    `swap`: frame i captured after frame i + 1."""
    gcs = flows.Sender(*GCS)
    out = []
    for i in range(n):
        frame = gcs.pack(flows.heartbeat(gcs=True) if i % 20 == 0 else flows.manual_control())
        if i not in lose:
            out.append((flows.T0 + i * 0.05, frame))
    for i in sorted(swap):
        j = next(k for k, (t, _) in enumerate(out) if round((t - flows.T0) / 0.05) == i)
        out[j], out[j + 1] = out[j + 1], out[j]
    return out


def test_a_dropout_longer_than_the_counter_is_not_a_replay(cli: Cli, tmp_path: Path) -> None:
    """Frames 300..499 lost (200 > 127: the 8-bit counter cannot show it; the next frames look like numbers
    already used) and every frame after 256 a copy of the one 256 before: all in their place."""
    found = both(cli, flows.write_tlog(tmp_path, neutral_stream(1200, lose=set(range(300, 500)))))
    assert "replayed-command" not in found


def test_reordered_copies_are_not_replays(cli: Cli, tmp_path: Path) -> None:
    """Copies (after the wrap) captured one frame late: each fills the gap its successor left."""
    found = both(cli, flows.write_tlog(tmp_path, neutral_stream(900, swap={301, 433, 611, 777})))
    assert "replayed-command" not in found


def test_wraps_with_loss_and_a_restart_are_not_replays(cli: Cli, tmp_path: Path) -> None:
    """Losses of 1 to 100 frames, then the GCS restarts (its counter from 0 again, the same bytes as its
    first frames): in place."""
    first = neutral_stream(700, lose={50, 260, 400} | set(range(520, 620)))
    again = neutral_stream(300)
    entries = first + [(t + 40.0, f) for t, f in again]
    found = both(cli, flows.write_tlog(tmp_path, entries))
    assert "replayed-command" not in found


def test_two_channels_with_their_own_counters(cli: Cli, tmp_path: Path) -> None:
    """One GCS talking to two vehicles over two UDP links, a counter per link (MAVLink's per channel), the
    same neutral MANUAL_CONTROL bytes on both: no replay."""
    a, b = flows.Sender(*GCS), flows.Sender(*GCS)
    packets = []
    for i in range(600):
        packets.append((("10.0.0.1", 14550), ("10.0.0.2", 14555), a.pack(flows.manual_control())))
        packets.append((("10.0.0.1", 14551), ("10.0.0.3", 14555), b.pack(flows.manual_control())))
    path = flows.write_udp_pcap(tmp_path / "two.pcap", packets)
    found = both(cli, str(path))
    assert "replayed-command" not in found


def test_a_recorded_run_sent_again_behind_the_counter(cli: Cli, tmp_path: Path) -> None:
    """Three COMMAND_LONGs (frames 41-43 of the tlog, seq 40-42) recorded and sent again as frames 101-103
    while the GCS's neutral stream goes on (its counter at 99, so 40 is 197 ahead: behind it, in the 8-bit
    counter's terms): every copy is behind a counter that then runs on (100 next), 3 replays, listed with
    their originals."""
    entries = flows.run_sent_again(flows.Sender(*GCS), lambda i: 40 <= i < 43, 100, lambda i: flows.manual_control())
    (replay,) = both(cli, flows.write_tlog(tmp_path, entries))["replayed-command"]
    assert replay["frames"] == [41, 101, 42, 102, 43, 103]  # (original, copy) each, in the order they came
    assert "COMMAND_LONG 3" in replay["message"]


def test_a_recorded_run_sent_again_ahead_of_the_counter(cli: Cli, tmp_path: Path) -> None:
    """The three COMMAND_LONGs (seq 40-42, records 41-43) sent again after the GCS's frame numbered 199 (tlog
    record 200): 40 is 97 ahead of 199, a jump forward, and the copies follow it number by number; the GCS's
    own frames then fill 200..39 and reach 40 again (its frame 296), so the run was ahead: 3 replays."""
    entries = flows.run_sent_again(flows.Sender(*GCS), lambda i: 40 <= i < 43, 200)  # (x = i: i < 1000)
    (replay,) = both(cli, flows.write_tlog(tmp_path, entries))["replayed-command"]
    assert replay["frames"] == [41, 201, 42, 202, 43, 203]


def test_a_copy_ahead_of_the_counter(cli: Cli, tmp_path: Path) -> None:
    """A COMMAND_LONG with seq 90 (frame 91) copied and sent in the next cycle as tlog record 315, after the
    GCS's frame numbered 57 (33 ahead: a jump forward): the GCS's own frames then fill 58..89 and reach 90
    again before passing it, so the copy was ahead of the counter."""
    gcs = flows.Sender(*GCS)
    entries, copy = [], b""
    for i in range(600):
        if i == 256 + 58:
            entries.append((flows.T0 + i * 0.05 - 0.01, copy))
        frame = gcs.pack(flows.command_long(31, float(i)) if i == 90 else flows.heartbeat(gcs=True)
                         if i % 7 == 0 else flows.manual_control(x=i % 1000))
        if i == 90:
            copy = frame
        entries.append((flows.T0 + i * 0.05, frame))
    (replay,) = both(cli, flows.write_tlog(tmp_path, entries))["replayed-command"]
    assert replay["frames"] == [91, 315] and "COMMAND_LONG 1" in replay["message"]


def test_a_signed_command_sent_twice_is_a_replay_and_audit_says_so(cli: Cli, tmp_path: Path) -> None:
    """A signed COMMAND_LONG (timestamp T) and the same bytes again: a signature timestamp that did not advance,
    whatever the sequence says. Without a key stats reports it, and audit (the security command) too."""
    mav = signer(b"\x42" * 32, *GCS)
    cmd = command_long(mav)
    frames = [flows.heartbeat(gcs=True), None, flows.heartbeat(gcs=True)]
    entries = []
    for i, m in enumerate(frames):
        entries.append((flows.T0 + i, cmd if m is None else bytes(m.pack(mav))))  # type: ignore[attr-defined]
        mav.signing.timestamp += 1
    entries.append((flows.T0 + 5, cmd))  # record 4: the copy
    path = flows.write_tlog(tmp_path, entries)
    (replay,) = both(cli, path)["replayed-command"]
    assert replay["frames"] == [2, 4]
    text = cli("audit", path)
    assert "replayed-command" in text.out and text.status == 1


# Real flights: every byte-for-byte repeat of a command or setpoint message, read with pymavlink, is in its
# place (the sender's previous frame's number before it and its next frame's after it, each within 127
# ahead), so they hold no replay.
REAL = ["px4_2018_params_offboard.tlog", "ardusub_log_tools_small.tlog", "ap_rover_mission_fence_rally_params.tlog",
        "ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog", "bluerobotics_mavlink_server_blueos_00025.tlog",
        "ap_hw_copter_cubeorange_raw_serial_corrupt_adsb_v1.raw"]


@pytest.mark.parametrize("name", REAL)
def test_real_flights_hold_no_replay(name: str, real_captures: Path, cli: Cli) -> None:
    msgs = pymavlink_read(real_captures / name)
    by_sender: dict[tuple[int, int], list] = {}
    for m in msgs:
        by_sender.setdefault(m.src, []).append(m)
    repeats = 0
    for ms in by_sender.values():
        seen = set()
        for k, m in enumerate(ms):
            raw = bytes(m.msg.get_msgbuf())
            if m.name not in COMMANDING:
                continue
            if raw in seen and 0 < k < len(ms) - 1:
                c, p, n = m.msg.get_seq(), ms[k - 1].msg.get_seq(), ms[k + 1].msg.get_seq()
                assert 1 <= (c - p) % 256 <= 127 and 1 <= (n - c) % 256 <= 127, (name, m.index)
                repeats += 1
            seen.add(raw)
    doc = cli.json("stats", str(real_captures / name))
    assert not [f for f in doc["findings"] if f["code"] == "replayed-command"], (name, repeats)


BUNDLED = ["commands_ack.pcap", "gcs_takeover.pcap", "gps_spoof.pcap", "ftp_lua_upload.pcap", "signed_udp.pcap",
           "stats_loss.pcap", "damaged.pcap", "key_exchange_udp.pcap"]


@pytest.mark.parametrize("name", BUNDLED)
def test_audit_shows_every_security_finding_of_stats(name: str, cli: Cli) -> None:
    """The bundled captures built with attacks in them (captures/README.md): every finding of the security
    group that stats reports, audit reports word for word (both run the one expert pass)."""
    from tests.conftest import CAPTURES

    both(cli, str(CAPTURES / name))
