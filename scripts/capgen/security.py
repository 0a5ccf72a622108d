"""Captures for the security layer (docs/security.md): SecureMAV payload encryption and the X25519 key
exchange with re-keying, signed over the ciphertext as SecureMAV does."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path
from random import Random
from typing import Any

import pymavlink.dialects.v20.common as mav2

from .constants import (
    BASE_TIME_US,
    GCS_COMPID,
    GCS_LINK_ID,
    GCS_SYSID,
    GCS_UDP_PORT,
    LINKTYPE_ETHERNET,
    LOOPBACK_V4,
    MAV_AUTOPILOT_PX4,
    REPO,
    SENSORS_PRESENT,
    SIGNING_EPOCH_US,
    SIGNING_KEY,
    VEHICLE_BOOT_OFFSET_MS,
    VEHICLE_COMPID,
    VEHICLE_LINK_ID,
    VEHICLE_SYSID,
    VEHICLE_UDP_PORT,
)
from .encode import encode_frame
from .frames import Endpoint, Frame, Send
from .kex import KEY_EXCHANGE_MSGID, epoch_keys, key_exchange_crc_extra, key_exchange_payload, public_key, shared_secret
from .packets import UdpFlow
from .story import SHORT_STORY, vehicle_state
from .summary import summarize_packets
from .telemetry import gcs_heartbeat, vehicle_heartbeat
from .writers import write_pcap

SECUREMAV_AES_METHOD = 2  # SecureMAV's AES method id is not public: this capture uses 2 (--cipher 2=...)
SECUREMAV_AES_KEY = bytes.fromhex("7C852089FFDB16126DBEE7C968A751B5")  # their published test key
SECUREMAV_XOR_METHOD = 7  # SecureMAV's test cipher: XOR 0xAB
SECUREMAV_START_US = 5_000_000  # encryption switched on 5 s into the capture
KEX_GCS_PRIVATE = hashlib.sha256(b"mavscope key exchange: gcs static key").digest()
KEX_EPOCHS = ((1, 3_000_000), (2, 12_000_000), (3, 22_000_000))  # (key id, capture time of the exchange)
KEX_AES_GCM_METHOD = 6


def kex_vehicle_private(key_id: int) -> bytes:
    """The vehicle's X25519 private key for epoch `key_id`: fixed, so the README can publish it."""
    return hashlib.sha256(f"mavscope key exchange: vehicle epoch {key_id}".encode()).digest()


class SecureSender:
    """A sender whose payloads pymavlink encodes and `encode.encode_frame` encrypts and signs
    (SecureMAV's order: encrypt, then CRC and signature over the ciphertext)."""

    def __init__(self, sysid: int, compid: int, link_id: int) -> None:
        self.ep = Endpoint(mav2, sysid, compid)
        self.link_id = link_id
        self.timestamp = 0

    def payload(self, build: Callable[[Any], Any]) -> tuple[int, bytes, int]:
        """(msgid, trimmed plaintext payload, CRC_EXTRA) of a message as pymavlink encodes it."""
        msg = build(self.ep.mav)
        data = msg.pack(self.ep.mav)
        return msg.get_msgId(), data[10:10 + data[1]], msg.crc_extra

    def frame(self, t_us: int, msgid: int, payload: bytes, crc_extra: int, signing_key: bytes | None = None,
              **cipher: Any) -> Frame:
        """The next frame of this sender, sent at capture time `t_us`; signed when `signing_key` is given
        (timestamps follow the capture clock and strictly increase, as pymavlink's do)."""
        seq = self.ep.next_seq()
        if signing_key is not None:
            self.timestamp = max(self.timestamp + 1, (BASE_TIME_US + t_us - SIGNING_EPOCH_US) // 10)
        data = encode_frame(msgid, payload, crc_extra, seq=seq, sysid=self.ep.mav.srcSystem,
                            compid=self.ep.mav.srcComponent, signing_key=signing_key, link_id=self.link_id,
                            timestamp=self.timestamp, **cipher)
        return Frame(data, self.ep.mav.srcSystem, self.ep.mav.srcComponent, seq, msgid, 2, signing_key is not None)


def _udp_capture(outdir: Path, name: str, sends: list[Send], rng: Random) -> dict[str, Any]:
    """Write `sends` as one datagram each between the loopback ports, in time order."""
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = [flow.packet(s) for s in sorted(sends, key=lambda s: s.t_us)]
    offsets = write_pcap(outdir / name, LINKTYPE_ETHERNET, pkts)
    return summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)


def _secure_heartbeat_and_status(script: list[Any], rng: Random, sec: int, quad: Any, state: Any) -> None:
    """The vehicle's HEARTBEAT and SYS_STATUS of second `sec` in the secure sessions' scripts."""
    script.append((sec * 1_000_000 + 1_000 + rng.randint(0, 500), "vehicle", lambda mav: quad(mav, state, 0)))
    script.append((sec * 1_000_000 + 2_000 + rng.randint(0, 500), "vehicle",
                   lambda mav: mav.sys_status_encode(SENSORS_PRESENT, SENSORS_PRESENT, SENSORS_PRESENT, 250,
                                                     15_800 - sec * 2, -1, 87 - sec // 4, 0, 0, 0, 0, 0, 0)))


def securemav_udp(outdir: Path) -> dict[str, Any]:
    """20 s, plaintext for 5 s, then SecureMAV: vehicle payloads AES-128-CTR (method 2, counter restarted
    every frame), GCS heartbeats XOR 0xAB (method 7). Vehicle frames are signed over the ciphertext."""
    rng = Random(15)
    vehicle = SecureSender(VEHICLE_SYSID, VEHICLE_COMPID, VEHICLE_LINK_ID)
    gcs = SecureSender(GCS_SYSID, GCS_COMPID, GCS_LINK_ID)
    state = vehicle_state(SHORT_STORY, 0.0)
    quad = vehicle_heartbeat(MAV_AUTOPILOT_PX4)
    script: list[tuple[int, str, Callable[[Any], Any]]] = []
    for sec in range(20):
        _secure_heartbeat_and_status(script, rng, sec, quad, state)
        for q in range(4):
            t = sec * 1_000_000 + q * 250_000 + 100_000 + rng.randint(0, 999)
            script.append((t, "vehicle", lambda mav, t=t, q=q: mav.attitude_encode(
                VEHICLE_BOOT_OFFSET_MS + t // 1000, 0.01 * q, -0.02, 1.5 + t / 1e9, 0.001, 0.0, -0.002)))
        script.append((sec * 1_000_000 + 500_000 + rng.randint(0, 2_000), "gcs",
                       lambda mav: gcs_heartbeat(mav, state, 0)))
    sends: list[Send] = []
    encrypted = {"vehicle": 0, "gcs": 0}
    for t_us, side, build in sorted(script, key=lambda e: e[0]):
        sender = vehicle if side == "vehicle" else gcs
        msgid, payload, crc_extra = sender.payload(build)
        cipher: dict[str, Any] = {}
        if t_us >= SECUREMAV_START_US:
            encrypted[side] += 1
            cipher = ({"method": SECUREMAV_AES_METHOD, "scheme": "aes-128-ctr", "key": SECUREMAV_AES_KEY}
                      if side == "vehicle" else {"method": SECUREMAV_XOR_METHOD, "scheme": "xor", "key": b"\xab"})
        frame = sender.frame(t_us, msgid, payload, crc_extra, SIGNING_KEY if side == "vehicle" else None, **cipher)
        sends.append(Send(t_us, side, [frame]))
    summary = _udp_capture(outdir, "securemav_udp.pcap", sends, rng)
    summary["truth"] = {"aes_method": SECUREMAV_AES_METHOD, "aes_key": SECUREMAV_AES_KEY.hex(), "aes_iv": "00" * 16,
                        "xor_method": SECUREMAV_XOR_METHOD, "encrypted_from_s": SECUREMAV_START_US / 1e6,
                        "encrypted_vehicle_frames": encrypted["vehicle"], "encrypted_gcs_frames": encrypted["gcs"]}
    return summary


def key_exchange_udp(outdir: Path) -> dict[str, Any]:
    """30 s: unsigned plaintext for 3 s, then MAVSCOPE_KEY_EXCHANGE (X25519) opens epoch 1; re-keyed at
    12 s (epoch 2) and 22 s (epoch 3). From each exchange both sides sign with the epoch's signing key
    and the vehicle encrypts ATTITUDE and SYS_STATUS with the aes-gcm profile (method 6, session id =
    key id); HEARTBEATs stay readable."""
    rng = Random(16)
    crc_extra = key_exchange_crc_extra(REPO / "dissectors" / "mavscope.xml")
    vehicle = SecureSender(VEHICLE_SYSID, VEHICLE_COMPID, VEHICLE_LINK_ID)
    gcs = SecureSender(GCS_SYSID, GCS_COMPID, GCS_LINK_ID)
    gcs_pub = public_key(KEX_GCS_PRIVATE)
    state = vehicle_state(SHORT_STORY, 0.0)
    quad = vehicle_heartbeat(MAV_AUTOPILOT_PX4)
    script: list[tuple[int, str, Any]] = []
    for sec in range(30):
        _secure_heartbeat_and_status(script, rng, sec, quad, state)
        for q in range(2):
            t = sec * 1_000_000 + q * 500_000 + 100_000 + rng.randint(0, 999)
            script.append((t, "vehicle", lambda mav, t=t: mav.attitude_encode(
                VEHICLE_BOOT_OFFSET_MS + t // 1000, 0.01, -0.02, 1.5 + t / 1e9, 0.001, 0.0, -0.002)))
        script.append((sec * 1_000_000 + 500_000 + rng.randint(0, 2_000), "gcs",
                       lambda mav: gcs_heartbeat(mav, state, 0)))
    epochs = []
    for key_id, t_ex in KEX_EPOCHS:
        v_priv = kex_vehicle_private(key_id)
        script.append((t_ex, "gcs", ("kex", key_id, gcs_pub, (VEHICLE_SYSID, VEHICLE_COMPID))))
        v_pub = public_key(v_priv)
        script.append((t_ex + 50_000, "vehicle", ("kex", key_id, v_pub, (GCS_SYSID, GCS_COMPID))))
        signing, gcm = epoch_keys(shared_secret(v_priv, gcs_pub), key_id, v_pub, gcs_pub)
        epochs.append({"key_id": key_id, "exchange_s": t_ex / 1e6, "vehicle_private": v_priv.hex(),
                       "signing_key": signing.hex(), "aes_gcm_key": gcm.hex(), "t_us": t_ex,
                       "signing": signing, "gcm": gcm})
    counters: dict[int, int] = {}
    sends: list[Send] = []
    for t_us, side, build in sorted(script, key=lambda e: e[0]):
        sender = vehicle if side == "vehicle" else gcs
        current = [e for e in epochs if e["t_us"] + 200_000 <= t_us]  # both sides switch 200 ms after
        epoch = current[-1] if current else None
        signing_key = epoch["signing"] if epoch is not None else None
        if isinstance(build, tuple):  # the key exchange: sent in clear, signed with the previous epoch's key
            _, key_id, public, target = build
            payload = key_exchange_payload(BASE_TIME_US + t_us, key_id, *target, public)
            previous = [e for e in epochs if e["key_id"] < key_id]
            sk = previous[-1]["signing"] if previous else None
            sends.append(Send(t_us, side, [sender.frame(t_us, KEY_EXCHANGE_MSGID, payload, crc_extra, sk)]))
            continue
        msgid, payload, extra = sender.payload(build)
        cipher: dict[str, Any] = {}
        if epoch is not None and side == "vehicle" and msgid != 0:
            n = counters.get(epoch["key_id"], 0)
            counters[epoch["key_id"]] = n + 1
            cipher = {"method": KEX_AES_GCM_METHOD, "scheme": "aes-gcm", "key": epoch["gcm"],
                      "session_id": epoch["key_id"], "counter": n}
        sends.append(Send(t_us, side, [sender.frame(t_us, msgid, payload, extra, signing_key, **cipher)]))
    summary = _udp_capture(outdir, "key_exchange_udp.pcap", sends, rng)
    summary["truth"] = {
        "gcs_private": KEX_GCS_PRIVATE.hex(), "gcs_public": gcs_pub.hex(), "aes_gcm_method": KEX_AES_GCM_METHOD,
        "epochs": [{k: v for k, v in e.items() if k not in ("signing", "gcm", "t_us")} for e in epochs],
        "encrypted_frames": sum(counters.values()),
    }
    return summary
