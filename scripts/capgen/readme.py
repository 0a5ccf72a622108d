"""README.md of the captures: what each file shows, the keys, and the counts and truths a correct tool
reports, rendered from expected.json so that prose and data cannot disagree."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .constants import (
    BASE_TIME_US,
    GCS_COMPID,
    GCS_LINK_ID,
    GCS_SYSID,
    LINKTYPE_ETHERNET,
    LINKTYPE_LINUX_SLL2,
    SIGNING_KEY,
    SIGNING_PASSPHRASE,
    UNKNOWN_MSGID,
    VEHICLE_BOOT_OFFSET_MS,
    VEHICLE_COMPID,
    VEHICLE_LINK_ID,
    VEHICLE_SYSID,
    VEHICLE_UTC_OFFSET_US,
)
from .damaged import DamageCase

CAPTURE_NOTES = {
    "px4_sitl_udp.pcap": "PX4 SITL <-> QGC on 127.0.0.1:14580 <-> :14550, 60 s: telemetry, mission upload "
                         "(4 items), arm, DO_REPOSITION (COMMAND_INT), RTL; some datagrams hold 2-3 frames; "
                         "an ARP packet and a DNS query as noise",
    "px4_sitl_tcp.pcap": "the same kind of session over TCP to 127.0.0.1:5760, 20 s: handshake, frames split "
                         "across segments, pure ACKs, one retransmission, one out-of-order pair, FIN",
    "mavlink_v1_udp.pcap": "MAVLink v1 (ArduCopter-style), 20 s: HEARTBEAT, SYS_STATUS, ATTITUDE, GPS_RAW_INT, "
                           "COMMAND_LONG arm + COMMAND_ACK",
    "signed_udp.pcap": "every frame signed (vehicle link 0, GCS link 1), 20 s, arm and RTL with their ACKs",
    "damaged.pcap": "one error case per record, see below",
    "px4_sitl.tlog": "the vehicle's frames of the first 30 s of px4_sitl_udp.pcap as a QGC tlog",
    "serial_dump.raw": "10 s of the vehicle's frames as a serial byte stream, garbage between frames, one frame "
                       "cut short",
    "px4_sitl_sll2.pcapng": "two interfaces: Linux SLL2 + IPv6 [::1] (vehicle 1, µs) and Ethernet + 802.1Q VLAN 10 "
                            "+ IPv4 192.168.10.0/24 (vehicle 2, ns)",
}
CAPTURE_NOTES |= {
    "stats_loss.pcap": "30 s, one frame per datagram; 44 vehicle frames and 2 GCS heartbeats removed, one "
                       "datagram duplicated, 3 vehicle frames with a bad CRC (truth below)",
    "mission_resend.pcap": "mission transfers: a download, an upload with a resent item, a refused fence upload, "
                           "an abandoned upload (truth below)",
    "commands_ack.pcap": "commands and ACKs: accepted, denied, failed, a retry, an unanswered one, a command from "
                         "a new sysid, a replayed command, SETUP_SIGNING (truth below)",
    "clock_skew.pcap": "60 s, vehicle clock 2.5 s ahead gaining 250 ppm: SYSTEM_TIME, signed frames, TIMESYNC, "
                       "PING (truth below)",
}
CAPTURE_NOTES |= {
    "securemav_udp.pcap": "SecureMAV payload encryption: 5 s plaintext, then vehicle payloads AES-128-CTR (method 2) "
                          "and GCS heartbeats XOR 0xAB (method 7); vehicle frames signed (keys below)",
    "key_exchange_udp.pcap": "X25519 key exchange (MAVSCOPE_KEY_EXCHANGE) with re-keying: signed frames and aes-gcm "
                             "payloads (method 6) under three epochs' keys (keys below)",
}
CAPTURE_NOTES |= {
    "ftp_params.pcap": "ArduPilot-like vehicle: @PARAM/param.pck read over MAVLink FTP (burst reads), parameter sets "
                       "from the signed GCS and an unsigned second system, a PARAM_EXT_SET to a camera, a second "
                       "param.pck read with a lost packet read again (truth: ftp_params.truth.json)",
    "ftp_lua_upload.pcap": "a Lua script written to /APM/scripts over MAVLink FTP (a write retried after its ACK was "
                           "lost), read back (a burst lost and retried, a packet read again), a read with a packet "
                           "lost for good, listings, a removal through '..', parameters set by writing param.pck "
                           "(truth: ftp_lua_upload.truth.json)",
    "log_download.pcap": "LOG_REQUEST_LIST/LOG_ENTRY, a log downloaded with LOG_REQUEST_DATA/LOG_DATA (three packets "
                         "lost and asked for again), a second one cancelled with LOG_REQUEST_END "
                         "(truth: log_download.truth.json)",
    "gcs_takeover.pcap": "PX4 quadrotor flying a mission for its GCS (255/190); in flight a second GCS (sysid 42, "
                         "UDP port 14551) takes over: modes, MANUAL_CONTROL, mission clear, forced disarm at 25 m "
                         "(gcs_takeover.truth.json)",
    "gps_spoof.pcap": "ArduCopter flying north: GNSS jammed for 4 s, then spoofed 700 m east (GPS and then EKF "
                      "position jump), EKF GPS glitch, EKF failsafe LAND, GNSS time one hour ahead "
                      "(gps_spoof.truth.json)",
}
LINKTYPE_NAMES = {LINKTYPE_ETHERNET: "Ethernet (1)", LINKTYPE_LINUX_SLL2: "Linux SLL2 (276)"}


def render_readme(expected: dict[str, Any], cases: Sequence[DamageCase]) -> str:
    """The README up to its analysis and security sections: files, keys, counts, damaged.pcap case by case."""
    key_hex = SIGNING_KEY.hex()
    udp, tcp, serial = expected["px4_sitl_udp.pcap"], expected["px4_sitl_tcp.pcap"], expected["serial_dump.raw"]
    rows = []
    for name, e in expected.items():
        link = ", ".join(LINKTYPE_NAMES[lt] for lt in e["linktypes"]) or \
            {"tlog": "tlog (no link layer)", "raw": "raw byte stream"}[e["format"]]
        note = CAPTURE_NOTES[name] + (f"; key `{key_hex}`" if name == "signed_udp.pcap" else "")
        rows.append(f"| `{name}` | {note} | {link} | {e['records'] if e['records'] is not None else '-'} | "
                    f"{e['frames']} |")
    counts = [f"| `{n}` | {e['frames']} | {e['crc_ok']} | {e['crc_bad']} | {e['crc_unchecked']} | {e['v1']} | "
              f"{e['v2']} | {e['signed']} | {e['truncated']} | {e['skipped_bytes']} |" for n, e in expected.items()]
    damage = [f"| {c.record} | {c.what} | {c.expect} |" for c in cases]
    nl = "\n"
    return f"""# Sample captures

Generated by `scripts/make_captures.py`; do not edit by hand (this README and `expected.json` are
generated too). Regenerate with

    python scripts/make_captures.py captures        # or: make captures

The output is the same byte for byte on every run and machine; `tests/test_captures_reproducible.py`
checks that, and checks `px4_sitl_udp.pcap` against pymavlink.

MAVLink frames are encoded and signed by pymavlink 2.4.50 (`pymavlink.dialects.v20.common`,
`pymavlink.dialects.v10.common`), packets built by scapy with correct IP/UDP/TCP checksums, and the files
written with `struct`. Capture time starts at 2026-03-14T10:00:00Z (Unix {BASE_TIME_US // 1_000_000}).

| file | what it shows | link type | records | frames |
|---|---|---|---|---|
{nl.join(rows)}

Endpoints: vehicle sysid {VEHICLE_SYSID} compid {VEHICLE_COMPID} (PX4, MAV_TYPE_QUADROTOR; home 47.3977419 N
8.5455938 E, 488 m), GCS sysid {GCS_SYSID} compid {GCS_COMPID}. The vehicle's `time_boot_ms` is capture time +
{VEHICLE_BOOT_OFFSET_MS} ms; its UTC clock (SYSTEM_TIME, GPS_RAW_INT) runs {VEHICLE_UTC_OFFSET_US} µs ahead of
the capture clock.

## Signing key (`signed_udp.pcap`)

Passphrase `{SIGNING_PASSPHRASE}`, key = SHA-256(passphrase) as MAVProxy derives it:

    {key_hex}

Vehicle frames use link id {VEHICLE_LINK_ID}, GCS frames link id {GCS_LINK_ID}. Signature timestamps are the
capture time in units of 10 µs since 2015-01-01T00:00:00Z (strictly increasing per sender, as pymavlink
adds one after each frame).

## What a correct decoder reports

| file | frames | CRC ok | CRC bad | CRC unchecked | v1 | v2 | signed | truncated | skipped bytes |
|---|---|---|---|---|---|---|---|---|---|
{nl.join(counts)}

Definitions:

- **frame**: a complete frame (header, payload of the length the header says, CRC, and the signature when
  incompat flag 0x01 is set) that the decoder reports, whatever its CRC verdict. Bytes that TCP
  retransmits are counted once.
- **CRC ok / bad / unchecked**: `unchecked` when the message id is in no dialect the decoder knows, so its
  CRC_EXTRA is unknown (here only id {UNKNOWN_MSGID}, which is in no pymavlink dialect); never `bad`.
- **truncated**: a frame cut short by the end of its datagram, of the capture record, or (in a byte stream)
  by the next frame: reported as a truncated-frame note, **not** counted under frames in this table.
  (`read -T jsonl` and `stats` list each one as a frame with `crc_status` `truncated`, so their totals
  are frames + truncated: `stats` prints the split, e.g. "CRC bad 2, ok 7, truncated 2, unchecked 1".)
- **skipped bytes**: bytes that belong to no frame and to no truncated frame (garbage, stray start bytes).

`expected.json` holds these counts per file and, per frame in capture order, `frame_list` entries
`[record_number, index_in_record, sysid, compid, seq, msgid]`, plus the parallel lists `frame_offsets`
(file offset of the frame's first byte) and `frame_crc` (`ok`/`bad`/`unchecked`), and `truncated_list`:
`[record_number, file offset]` of each truncated frame's first byte.

- `record_number` is 1-based over all records of the file (pcapng: over all packet blocks of both
  interfaces; tlog: one record per frame). For `serial_dump.raw` it is `null`: a raw stream has no records
  (the reader's chunking decides them), and `index_in_record` is the frame's 1-based position in the
  stream among the frames listed.
- A frame belongs to the record in which it completes: for datagrams the record holding it; for TCP the
  record after which the stream is contiguous up to the frame's last byte (retransmitted copies add
  nothing; a frame ending in the early-arriving half of the out-of-order pair completes with the
  later record, as Wireshark shows a reassembled PDU). `index_in_record` is 1-based among the frames
  completing in that record, in stream order. This is `Frame.record` / `Frame.index` in mavscope.

## `damaged.pcap`, record by record

| record | what is in it | what a correct tool reports |
|---|---|---|
{nl.join(damage)}

## `serial_dump.raw`

Garbage (no 0xFD/0xFE) sits between some frames ({serial['skipped_bytes']} bytes in all), and one frame
is cut after 16 bytes at file offset {serial['truncated_list'][0][1]}, directly followed by the next frame: a
correct tool reports the cut frame as a truncated frame (not as a frame) and still decodes the frame that
follows it.

## Other events

- `px4_sitl_udp.pcap`: records {udp['events']['noise_records']} are not MAVLink (ARP, DNS, ARP, DNS).
- `px4_sitl_tcp.pcap`: the handshake is records 1-3 and the FIN exchange the last four; record
  {tcp['events']['retransmission'][1]} retransmits record {tcp['events']['retransmission'][0]} (same sequence \
number, same bytes); records {tcp['events']['out_of_order'][0]} and {tcp['events']['out_of_order'][1]} are \
out of order (the later bytes first).

## Where pymavlink's robust parser differs

pymavlink (`robust_parsing = True`) is not a correct tool for `damaged.pcap` and `serial_dump.raw`, so
a cross-check against it must expect these differences:

- `damaged.pcap` record 6: pymavlink returns `MAVLink_unknown` (CRC not checkable), not bad data.
- `damaged.pcap` record 7: pymavlink drops the frame with the unknown incompat flag (bad data).
- `damaged.pcap` record 8: pymavlink reads the stray `fe` as a v1 frame of 253 payload bytes, waits for
  bytes the datagram does not have, and so finds neither frame.
- `serial_dump.raw`: pymavlink reads the cut frame's length, takes the next frame's bytes as its tail
  (bad CRC) and loses that next frame: it finds one CRC-valid frame fewer than listed here.
"""


def render_analysis_truth(expected: dict[str, Any]) -> str:
    """The README section on the captures built for statistics, mission, command and clock analysis."""
    loss = expected["stats_loss.pcap"]["truth"]
    mission = expected["mission_resend.pcap"]["truth"]["transfers"]
    cmds = expected["commands_ack.pcap"]["truth"]
    clock = expected["clock_skew.pcap"]["truth"]
    links = "\n".join(f"| {k} | {v['sent']} | {v['received']} | {v['lost']} | {v['duplicates']} | {v['crc_bad']} |"
                      for k, v in loss["links"].items())
    transfers = "\n".join(
        f"| {i} | {t['direction']} | {t['from']} -> {t['to']} | {t['mission_type']} | {t['count']} | "
        f"{'yes' if t['complete'] else 'no'} | "
        f"{', '.join(f'{k}: {v}' for k, v in t.items() if k in ('resent', 'result', 'reason', 'items_received'))} |"
        for i, t in enumerate(mission, 1))
    commands = "\n".join(
        f"| {c['command']} | {c['kind']} | {c['from']} | {c['result'] if c['result'] is not None else 'none'} | "
        f"{c['retries']} | {c['latency_ms'] if c['latency_ms'] is not None else '-'} |" for c in cmds["commands"])
    return f"""
## Analysis truth (`stats`, `mission`, `commands`, `timeline`, expert findings)

`stats_loss.pcap`: {loss['removed_vehicle_frames']}, and GCS {loss['removed_gcs_frames']}, were removed; one
vehicle datagram appears twice (a duplicate, not a loss); three vehicle frames have one payload bit flipped
(header intact, CRC bad).

| link (sysid/compid) | frames sent | frames in the capture | lost | duplicates | CRC bad |
|---|---|---|---|---|---|
{links}

`mission_resend.pcap` (items as MISSION_ITEM_INT, frame MAV_FRAME_GLOBAL_RELATIVE_ALT_INT):

| # | direction | from -> to | mission type | count | complete | detail |
|---|---|---|---|---|---|---|
{transfers}

`commands_ack.pcap` (MAV_RESULT: 0 accepted, 2 denied, 4 failed; latency from the first transmission to
the ACK; the last row is record {cmds['replay_record']}, a byte-for-byte replay of record
{cmds['commands'][-1]['replay_of_record']}; the command from `rogue` comes from sysid {cmds['rogue'][0]} on UDP
port {cmds['rogue'][2]}, a system not seen before; record {cmds['setup_signing_record']} is a SETUP_SIGNING that
carries a key in clear):

| command | message | from | result | retries | latency ms |
|---|---|---|---|---|---|
{commands}

`clock_skew.pcap`: the GCS clock is the capture clock. The vehicle's UTC clock (SYSTEM_TIME.time_unix_usec and
its signature timestamps, link {VEHICLE_LINK_ID}) is {clock['vehicle_utc_offset_s']} s ahead at the capture
start and gains {clock['vehicle_drift_ppm']} ppm; its boot clock (time_boot_ms, TIMESYNC tc1) started
{clock['vehicle_boot_before_capture_s']} s (by its own clock) before the capture and drifts the same.
TIMESYNC round trips (ms): {', '.join(map(str, clock['timesync_rtt_ms']))}; PING round trips (ms):
{', '.join(map(str, clock['ping_rtt_ms']))}.
"""



def render_security_captures(expected: dict[str, Any]) -> str:
    """The README section on securemav_udp.pcap and key_exchange_udp.pcap: keys and what to expect."""
    sm = expected["securemav_udp.pcap"]["truth"]
    kx = expected["key_exchange_udp.pcap"]["truth"]
    epochs = "\n".join(f"| {e['key_id']} | {e['exchange_s']} | `{e['vehicle_private']}` | `{e['signing_key']}` | "
                       f"`{e['aes_gcm_key']}` |" for e in kx["epochs"])
    aes_cipher = f"{sm['aes_method']}=aes-128-ctr:hex:{sm['aes_key']}"
    return f"""
## Security captures (`mavscope verify`, `audit`, `read --key/--cipher/--ecdh-private`; docs/security.md)

`securemav_udp.pcap`: SecureMAV payload encryption from {sm['encrypted_from_s']} s on. Vehicle payloads are
AES-128-CTR (method {sm['aes_method']}, SecureMAV's test key `{sm['aes_key']}`, IV 16 zero bytes, counter restarted
for every frame: {sm['encrypted_vehicle_frames']} frames); GCS heartbeats use SecureMAV's test cipher (method
{sm['xor_method']}, XOR 0xAB: {sm['encrypted_gcs_frames']} frames). Vehicle frames are signed (key above, link
{VEHICLE_LINK_ID}) over the ciphertext, as SecureMAV computes CRC and signature after encrypting. The plaintext
frames of the first seconds are known plaintext for `mavscope audit` (keystream-reuse):

    mavscope read captures/securemav_udp.pcap --key passphrase:{SIGNING_PASSPHRASE} --cipher {aes_cipher}
    mavscope audit captures/securemav_udp.pcap

`key_exchange_udp.pcap`: MAVSCOPE_KEY_EXCHANGE (id 65100, X25519) between the GCS (static key) and the
vehicle (a fresh key per epoch), unsigned plaintext before the first exchange, re-keyed twice. Both sides
switch to an epoch's keys 200 ms after its exchange; each exchange after the first is signed with the
previous epoch's key. The vehicle encrypts ATTITUDE and SYS_STATUS with the aes-gcm profile (method
{kx['aes_gcm_method']}, session id = key id, counter from 0 per epoch: {kx['encrypted_frames']} frames).
GCS private key `{kx['gcs_private']}` (public `{kx['gcs_public']}`):

    mavscope read captures/key_exchange_udp.pcap --ecdh-private hex:{kx['gcs_private']}
    mavscope verify captures/key_exchange_udp.pcap --ecdh-private hex:{kx['gcs_private']}

| key id | exchange at s | vehicle private key | signing key (HKDF) | aes-gcm master key (HKDF) |
|---|---|---|---|---|
{epochs}
"""


def render_incidents(outdir: Path) -> str:
    """The README section on the incident captures, from their truth files."""
    take = json.loads((outdir / "gcs_takeover.truth.json").read_text(encoding="utf-8"))
    spoof = json.loads((outdir / "gps_spoof.truth.json").read_text(encoding="utf-8"))
    modes = ", ".join(f"{m['from']} -> {m['to']} (record {m['record']})" for m in take["modes"])
    findings = "\n".join(f"| `{name}` | {code} | {', '.join(' '.join(map(str, fr)) for fr in frames)} |"
                         for name, t in (("gcs_takeover.pcap", take), ("gps_spoof.pcap", spoof))
                         for code, frames in t["findings"].items())
    return f"""
## Incident captures (`mavscope events`, `track`, `plot`, expert findings)

Each has a truth file written by the generator from what it sent (record numbers of the tagged messages,
the states it put in the vehicle's HEARTBEATs); the tests compare mavscope's answers with it.

`gcs_takeover.pcap` (PX4, custom modes as px4_custom_mode.h packs them): the vehicle's modes {modes}. The
intruder ({take['intruder'][0]}/{take['intruder'][1]}, UDP port {take['intruder_udp_port']}) sends
{len(take['intruder_control_records'])} control frames while the vehicle is armed, clears the mission (record
{take['mission_clear_record']}) and force-disarms it at {take['disarm_in_air']['relative_alt_m']} m (command record
{take['disarm_in_air']['command_record']}, disarmed HEARTBEAT record {take['disarm_in_air']['heartbeat_record']}).

`gps_spoof.pcap` (ArduCopter, ardupilotmega dialect): jammed from {spoof['jamming']['from_s']} s to
{spoof['jamming']['until_s']} s (satellites {spoof['jamming']['satellites'][0]} -> {spoof['jamming']['satellites'][1]},
first record {spoof['jamming']['first_record']}); the GPS position jumps {spoof['spoof']['jump_east_m']} m east at
record {spoof['spoof']['gps_record']} while the vehicle reports {spoof['spoof']['speed_mps']} m/s, the EKF output
follows at record {spoof['spoof']['global_position_record']}; SYSTEM_TIME jumps {spoof['time_jump']['seconds']} s at
record {spoof['time_jump']['record']}.

| capture | finding | frames (each finding's list) |
|---|---|---|
{findings}
"""


def render_objects_truth(expected: dict[str, Any]) -> str:
    """The README section on the object and parameter captures: where their truth is and what it holds."""
    names = ("ftp_params.pcap", "ftp_lua_upload.pcap", "log_download.pcap")
    rows = "\n".join(f"| `{n}` | `{expected[n]['truth']}` | {expected[n]['frames']} |" for n in names)
    return f"""
## Objects and parameters truth (`objects`, `params`)

Each of these captures comes with a truth file written by the generator from what it sent (never by
decoding): every object (FTP path, direction, sender, receiver, size, SHA-256 of the bytes as a correct tool
rebuilds them, with zeros where a packet was lost for good, completeness and gaps), the FTP operations,
and for the parameter captures the initial and final parameter values and the timeline of sets (value,
previous value, sender, whether the vehicle confirmed it, retries, security category).

| capture | truth | frames |
|---|---|---|
{rows}

The param.pck files are packed as ArduPilot's AP_Filesystem_Param does (`scripts/capgen/parampck.py`: pad
bytes keep each value inside one 239-byte read block); FTP packets are built with pymavlink's
`mavftp_op.FTP_OP`. Frames "lost" were encoded (their sender's sequence number advances) but left out.
"""
