"""The tests' one set of fixture builders: capture files and MAVLink frames.

Files are written with mavscope's own writers (capture/writer.py, tested against the formats' definitions
in tests/capture) around packets from capture/synth.py (Ethernet/IPv4 or IPv6/UDP with correct checksums);
frames are encoded by pymavlink, an implementation independent of mavscope's framer, signed by it when the
encoder is given a key. Files whose every byte a test chooses (byte order, time resolution, link headers,
checksums left 0) are packed by hand in tests/native/build.py, pcapng blocks with chosen options, byte order
and lengths by `pcapng_*` here; a test that needs a layout none of them makes (a broken header on purpose)
keeps its own and says why.

A tlog entry is an 8-byte big-endian timestamp in microseconds, then one frame (captures/README.md).
"""

from __future__ import annotations

import io
import struct
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import BinaryIO

from pymavlink.dialects.v10 import common as v1
from pymavlink.dialects.v20 import all as v2

from mavscope.capture.base import LINKTYPE_ETHERNET
from mavscope.capture.synth import udp_packet
from mavscope.capture.writer import DEFAULT_SNAPLEN, PcapWriter

Address = tuple[str, int]
Datagram = tuple[Address, Address, bytes]  # (source, destination, UDP payload)
EPOCH_2026 = (1_773_482_400 - 1_420_070_400) * 100_000  # signature timestamp of 2026-03-14T10:00:00Z


# --- capture files ---------------------------------------------------------------------------------


def pcap_bytes(records: Iterable[tuple[float | None, bytes]], linktype: int = LINKTYPE_ETHERNET,
               nanosecond: bool = False, snaplen: int = DEFAULT_SNAPLEN) -> bytes:
    """A little-endian classic pcap of (time, link-layer packet) records, in `linktype`."""
    buf = io.BytesIO()
    _write_pcap(buf, records, linktype, nanosecond, snaplen)
    return buf.getvalue()


def write_pcap(path: Path, records: Iterable[tuple[float | None, bytes]], linktype: int = LINKTYPE_ETHERNET,
               nanosecond: bool = False, snaplen: int = DEFAULT_SNAPLEN) -> Path:
    """`pcap_bytes` written to `path` as the records come."""
    _write_pcap(path, records, linktype, nanosecond, snaplen)
    return path


def _write_pcap(out: Path | BinaryIO, records: Iterable[tuple[float | None, bytes]], linktype: int,
                nanosecond: bool, snaplen: int) -> None:
    with PcapWriter(out, linktype, snaplen=snaplen, nanosecond=nanosecond) as w:
        for t, data in records:
            w.write(t, data)


def timed(items: Iterable[bytes], t0: float = 1.0, step: float = 1.0) -> list[tuple[float, bytes]]:
    """(time, item) records, one every `step` seconds from `t0` (for `write_pcap`, `pcap_bytes` or `tlog`)."""
    return [(t0 + i * step, item) for i, item in enumerate(items)]


def udp_records(datagrams: Sequence[Datagram], t0: float = 1.0, step: float = 1.0) -> list[tuple[float, bytes]]:
    """UDP datagrams as Ethernet records, one every `step` seconds from `t0`: IPv4, or IPv6 where an end is an
    IPv6 address (an IPv4 end then written IPv4-mapped)."""
    return timed((udp_packet(*src, *dst, payload) for src, dst, payload in datagrams), t0, step)


def write_udp_pcap(path: Path, datagrams: Sequence[Datagram], t0: float = 1.0, step: float = 1.0) -> Path:
    """`udp_records` as an Ethernet pcap."""
    return write_pcap(path, udp_records(datagrams, t0, step))


def pcapng_block(btype: int, body: bytes, e: str = "<") -> bytes:
    """One pcapng block of type `btype` in byte order `e` ("<" or ">"), its body padded to 4 bytes (pcapng
    spec, section 3.1: type, total length, body, total length again)."""
    body += b"\0" * (-len(body) & 3)
    n = 12 + len(body)
    return struct.pack(e + "II", btype, n) + body + struct.pack(e + "I", n)


def pcapng_shb(e: str = "<") -> bytes:
    """A Section Header Block: byte-order magic, version 1.0, section length -1 (not given)."""
    return pcapng_block(0x0A0D0D0A, struct.pack(e + "IHHq", 0x1A2B3C4D, 1, 0, -1), e)


def pcapng_idb(linktype: int, tsresol: int | None = None, tsoffset: int = 0, e: str = "<", snaplen: int = 0,
               options: bytes | None = None) -> bytes:
    """An Interface Description Block; its options if_tsresol (9) and if_tsoffset (14) where given, closed by
    opt_endofopt; or `options` as they are given (then closed by opt_endofopt even when empty)."""
    if options is None:
        opts = b""
        if tsresol is not None:
            opts += struct.pack(e + "HHB3x", 9, 1, tsresol)
        if tsoffset:
            opts += struct.pack(e + "HHq", 14, 8, tsoffset)
    else:
        opts = options
    if opts or options is not None:
        opts += struct.pack(e + "HH", 0, 0)
    return pcapng_block(1, struct.pack(e + "HHI", linktype, 0, snaplen) + opts, e)


def pcapng_epb(iface: int, ts: int, data: bytes, orig: int | None = None, e: str = "<") -> bytes:
    """An Enhanced Packet Block of interface `iface` at `ts` ticks (of its if_tsresol), `orig` the original
    length (default: the data's)."""
    body = struct.pack(e + "IIIII", iface, ts >> 32, ts & 0xFFFFFFFF, len(data), orig or len(data)) + data
    return pcapng_block(6, body, e)


def tlog_us(entries: Iterable[tuple[int, bytes]]) -> bytes:
    """A tlog of (microseconds since the epoch, frame) entries."""
    return b"".join(struct.pack(">Q", us) + frame for us, frame in entries)


def tlog_spaced(frames: Iterable[bytes], t0_us: int = 1_700_000_000_000_000, step_us: int = 1000) -> bytes:
    """A tlog of `frames`, the first at `t0_us` microseconds since the epoch, the rest `step_us` apart."""
    return tlog_us((t0_us + i * step_us, frame) for i, frame in enumerate(frames))


def tlog(entries: Iterable[tuple[float, bytes]]) -> bytes:
    """A tlog of (seconds since the epoch, frame) entries, times rounded to the microsecond."""
    return tlog_us((round(t * 1e6), frame) for t, frame in entries)


def write_tlog(tmp: Path, entries: list[tuple[float, bytes]], name: str = "flow.tlog") -> str:
    path = tmp / name
    path.write_bytes(tlog(entries))
    return str(path)


def write_raw(tmp: Path, frames: list[bytes], name: str = "cap.raw") -> str:
    """A raw byte stream (a serial log): the frames back to back."""
    path = tmp / name
    path.write_bytes(b"".join(frames))
    return str(path)


# --- MAVLink frames (pymavlink) ---------------------------------------------------------------------


def mav2(sysid: int = 1, compid: int = 1, seq: int = 0) -> v2.MAVLink:
    """A MAVLink 2 encoder for `sysid`/`compid` whose next frame has sequence number `seq`."""
    mav = v2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    mav.seq = seq
    return mav


def mav1(sysid: int = 1, compid: int = 1) -> v1.MAVLink:
    return v1.MAVLink(None, srcSystem=sysid, srcComponent=compid)


def signer(key: bytes | None, sysid: int = 255, compid: int = 190, link_id: int = 1,
           timestamp: int = EPOCH_2026) -> v2.MAVLink:
    """A pymavlink encoder that signs with `key` (None: unsigned), explicit timestamps."""
    mav = mav2(sysid, compid)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.link_id = link_id
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = timestamp
    return mav


def heartbeat_msg(mav_type: int = 2, autopilot: int = 12, base_mode: int = 0, custom_mode: int = 0,
                  system_status: int = 4, version: int = 3) -> v2.MAVLink_heartbeat_message:
    """A HEARTBEAT message (for an encoder's `pack`, or flows.Sender's)."""
    return v2.MAVLink_heartbeat_message(mav_type, autopilot, base_mode, custom_mode, system_status, version)


def vehicle_heartbeat_msg(armed: bool = False, custom_mode: int = 0, mav_type: int = 2, base_mode: int = 1,
                          system_status: int = 4, autopilot: int = 3) -> v2.MAVLink_heartbeat_message:
    """An ArduPilot vehicle's HEARTBEAT (by default a quadrotor), MAV_MODE_FLAG_SAFETY_ARMED (128) added to
    `base_mode` when `armed`; `custom_mode` is its flight mode (ArduCopter: 0 STABILIZE, 5 LOITER)."""
    return heartbeat_msg(mav_type, autopilot, base_mode | (128 if armed else 0), custom_mode, system_status)


def heartbeat(mav: v2.MAVLink | v1.MAVLink, mav_type: int = 2, autopilot: int = 12, base_mode: int = 81,
              custom_mode: int = 0, system_status: int = 4, version: int = 3) -> bytes:
    """The next HEARTBEAT frame of `mav` (MAVLink 1 or 2, signed if it signs); by default a quadrotor's
    (MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_PX4, base mode 81, MAV_STATE_ACTIVE)."""
    return bytes(mav.heartbeat_encode(mav_type, autopilot, base_mode, custom_mode, system_status, version).pack(mav))


def gcs_heartbeat(mav: v2.MAVLink | v1.MAVLink | None = None, base_mode: int = 0) -> bytes:
    """A ground station's HEARTBEAT (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID); without `mav`, the first frame of
    a MAVLink 2 ground station 255/190 (sequence 0)."""
    return heartbeat(mav or mav2(255, 190), 6, 8, base_mode)


def command_long_msg(command: int = 400, *params: float, target_system: int = 1, target_component: int = 1,
                     confirmation: int = 0) -> v2.MAVLink_command_long_message:
    """A COMMAND_LONG message: param1.. as given, the rest 0."""
    p = [*params, *[0.0] * (7 - len(params))]
    return v2.MAVLink_command_long_message(target_system, target_component, command, confirmation, *p)


def command_long(mav: v2.MAVLink | v1.MAVLink, command: int = 20, *params: float, target_system: int = 1,
                 target_component: int = 1, confirmation: int = 0) -> bytes:
    """The next COMMAND_LONG frame of `mav` (by default MAV_CMD_NAV_RETURN_TO_LAUNCH to 1/1)."""
    p = [*params, *[0.0] * (7 - len(params))]
    return bytes(mav.command_long_encode(target_system, target_component, command, confirmation, *p).pack(mav))


def gcs_arm(arm: float = 1, mav: v2.MAVLink | v1.MAVLink | None = None) -> bytes:
    """COMMAND_LONG MAV_CMD_COMPONENT_ARM_DISARM (400) to 1/1, param1 `arm` (1 arm, 0 disarm); without `mav`,
    the first frame of a MAVLink 2 ground station 255/190 (sequence 0)."""
    return command_long(mav or mav2(255, 190), 400, arm)


def statustext(mav: v2.MAVLink | v1.MAVLink, text: str = "hello", severity: int = 6) -> bytes:
    return bytes(mav.statustext_encode(severity, text.encode()).pack(mav))


def attitude(mav: v2.MAVLink | v1.MAVLink, time_boot_ms: int = 0, roll: float = 0.0, pitch: float = 0.0,
             yaw: float = 0.0) -> bytes:
    return bytes(mav.attitude_encode(time_boot_ms, roll, pitch, yaw, 0, 0, 0).pack(mav))


def radio_status(mav: v2.MAVLink) -> bytes:
    return bytes(mav.radio_status_encode(200, 190, 100, 50, 40, 0, 0).pack(mav))


def mixed_frames() -> list[bytes]:
    """Frames of each kind a framer meets, from 1/1: a quadrotor's HEARTBEAT, a STATUSTEXT whose text holds
    0xFD and 0xFE, COMMAND_LONG MAV_CMD_NAV_RETURN_TO_LAUNCH, a signed HEARTBEAT (key 32 zero bytes,
    timestamp 1000) and a MAVLink 1 HEARTBEAT (MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_ARDUPILOTMEGA, base mode 81)."""
    mav = mav2()
    parts = [heartbeat(mav), statustext(mav, "\xfd\xfe inside"), command_long(mav, 20)]
    mav.signing.secret_key = bytes(32)
    mav.signing.sign_outgoing = True
    mav.signing.timestamp = 1000
    return [*parts, heartbeat(mav), heartbeat(mav1(), 2, 3, 81)]
