"""Cross-check mavscope's framing against tshark running pymavlink's generated Wireshark Lua dissector.

For every UDP capture, each MAVLink frame's header fields and message id as printed by
``python -m mavscope read CAPTURE -T jsonl`` are compared with what the Lua dissector decodes in the same
capture record. The rules for which fields are compared (and for damaged frames, which are not compared)
are spelled out in docs/testing-tshark.md and implemented in :func:`compare_record`.

Without tshark, or when the Lua dissector cannot be generated or loaded, every test here skips with the
reason (visible in ``pytest -ra``); scripts/install-test-tools.sh installs tshark.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import CAPTURES, REAL_CAPTURES
from tests.conftest import ROOT as REPO
from tests.support import tshark  # the reference side

# UDP captures made by scripts/make_captures.py (`make captures`) and real ones from ../shared.
GENERATED_UDP_CAPTURES = (
    "px4_sitl_udp.pcap",
    "mavlink_v1_udp.pcap",
    "signed_udp.pcap",
    "damaged.pcap",
    "px4_sitl_sll2.pcapng",
)
REAL_UDP_CAPTURES = ("ipal_transcriber_MAVLink.pcap",)

MAVSCOPE_TIMEOUT_S = 600
DAMAGE_NOTES = frozenset({"truncated-frame"})  # note codes that mark a mavscope frame as damaged

Key = tuple[int | None, ...]


# --------------------------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="session")
def dissect(tshark_exe: str, lua_dissector: Path) -> Callable[[Path], tshark.TsharkRun]:
    """Run the Lua dissector over a capture, at most once per capture per session."""
    cache: dict[Path, tshark.TsharkRun] = {}

    def run(capture: Path) -> tshark.TsharkRun:
        key = capture.resolve()
        if key not in cache:
            try:
                cache[key] = tshark.run_lua_dissector(tshark_exe, lua_dissector, capture)
            except tshark.TsharkUnavailable as exc:
                pytest.skip(f"tshark cross-check skipped: {exc}")
        return cache[key]

    return run


def mavscope_jsonl(capture: Path) -> list[dict[str, Any]]:
    """mavscope's frames for ``capture``: one dict per line of ``mavscope read CAPTURE -T jsonl``.

    Skips when the mavscope CLI module does not exist yet; a CLI that exists and fails is a test failure.
    """
    if not (REPO / "mavscope" / "cli.py").is_file():
        pytest.skip("mavscope CLI (mavscope/cli.py) does not exist yet: nothing to compare with tshark")
    proc = subprocess.run(
        [sys.executable, "-m", "mavscope", "read", str(capture), "-T", "jsonl"],
        capture_output=True, text=True, timeout=MAVSCOPE_TIMEOUT_S, cwd=REPO, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, (
        f"mavscope read {capture.name} -T jsonl exited {proc.returncode}:\n{proc.stderr[-2000:]}"
    )
    return [json.loads(line) for line in proc.stdout.splitlines() if line.strip()]


# ------------------------------------------------------------------------------------------- comparison


def mav_key(obj: dict[str, Any]) -> Key:
    """The header of a mavscope frame as (version, len, incompat, compat, seq, sysid, compid, msgid).

    v1 frames have no flag bytes: their flags are None whatever mavscope prints for them.
    """
    v1 = obj.get("version") == 1
    return (
        obj.get("version"),
        obj.get("len"),
        None if v1 else obj.get("incompat_flags"),
        None if v1 else obj.get("compat_flags"),
        obj.get("seq"),
        obj.get("sysid"),
        obj.get("compid"),
        obj.get("msgid"),
    )


def lua_key(frame: tshark.LuaFrame) -> Key:
    """The header of a Lua-decoded frame, in the same shape as mav_key()."""
    return (
        frame.version,
        frame.length,
        frame.incompat_flags,
        frame.compat_flags,
        frame.seq,
        frame.sysid,
        frame.compid,
        frame.msgid,
    )


def mav_damaged(obj: dict[str, Any]) -> bool:
    """A mavscope frame is damaged when its CRC is not "ok" or it carries a truncation note."""
    codes = {n.get("code") for n in obj.get("notes") or [] if isinstance(n, dict)}
    return obj.get("crc_status") != "ok" or bool(codes & DAMAGE_NOTES)


@dataclass
class Comparison:
    """Tally of one capture's comparison; ``problems`` is empty when mavscope and tshark agree."""

    full: int = 0  # clean pairs compared on header, msgid, CRC value and signature
    header_only: int = 0  # pairs involving a damaged frame, compared on the header (incl. msgid) only
    lua_only: int = (
        0  # Lua frames failing pymavlink's CRC that mavscope does not report (Lua has no CRC check)
    )
    mavscope_only: int = 0  # damaged mavscope frames, or frames the Lua lost after losing sync
    unread: int = 0  # mavscope frames in a last record cut short by the end of the file: tshark skips it
    problems: list[str] = field(default_factory=list)

    def summary(self) -> str:
        """One line with the counts."""
        return (
            f"{self.full} frames fully compared, {self.header_only} header-only, "
            f"{self.lua_only} Lua-only (CRC-invalid), "
            f"{self.mavscope_only} mavscope-only (damaged/Lua lost sync), "
            f"{self.unread} in a record tshark did not read"
        )


def _describe(obj: dict[str, Any] | None, lua: tshark.LuaFrame | None) -> str:
    parts = []
    if obj is not None:
        parts.append(
            f"mavscope #{obj.get('index')} {mav_key(obj)} crc={obj.get('crc')} {obj.get('crc_status')}"
        )
    if lua is not None:
        parts.append(
            f"Lua #{lua.order}@{lua.pos} {lua_key(lua)} crc={lua.crc} "
            f"pymavlink:{tshark.pymavlink_crc_status(lua)}"
        )
    return "; ".join(parts)


def compare_pair(num: int, obj: dict[str, Any], lua: tshark.LuaFrame, out: Comparison) -> None:
    """Compare one aligned pair (same header key) according to the damage rules."""
    oracle = tshark.pymavlink_crc_status(lua)
    status = obj.get("crc_status")
    if (status == "ok" and oracle == "bad") or (status == "bad" and oracle == "ok"):
        out.problems.append(
            f"record {num}: CRC verdicts differ (mavscope vs pymavlink): {_describe(obj, lua)}"
        )
        return
    if mav_damaged(obj) or oracle != "ok":
        out.header_only += 1
        return
    out.full += 1
    if obj.get("crc") != lua.crc:
        out.problems.append(f"record {num}: CRC value differs: {_describe(obj, lua)}")
    sig = obj.get("signature")
    mav_sig = None if sig is None else (sig.get("link_id"), sig.get("timestamp"))
    lua_sig = (lua.link_id, lua.sig_timestamp) if lua.signed else None
    if mav_sig != lua_sig:
        out.problems.append(f"record {num}: signature (link_id, timestamp) {mav_sig} vs Lua {lua_sig}")


def compare_record(
    num: int, mav: Sequence[dict[str, Any]], record: tshark.LuaRecord | None, out: Comparison
) -> None:
    """Align and compare one capture record's frames; add disagreements to ``out.problems``.

    Both lists are walked in order. Frames whose header keys are equal are a pair (compare_pair).
    Otherwise a Lua frame that fails pymavlink's CRC check is skipped (the Lua takes any 0xFD/0xFE for a
    frame start), then a damaged mavscope frame is skipped; two clean frames that differ are a problem.
    Left-over mavscope frames are allowed when damaged or when the Lua lost sync in this record
    (garbage or a truncated header, an unknown message id, a Lua error, or a skipped CRC-invalid Lua
    frame); left-over Lua frames are allowed only when they fail pymavlink's CRC check.
    """
    lua = list(record.frames) if record is not None else []
    lua_skipped = 0
    i = j = 0
    while i < len(mav) and j < len(lua):
        if mav_key(mav[i]) == lua_key(lua[j]):
            compare_pair(num, mav[i], lua[j], out)
            i += 1
            j += 1
        elif tshark.pymavlink_crc_status(lua[j]) != "ok":
            lua_skipped += 1
            j += 1
        elif mav_damaged(mav[i]):
            out.mavscope_only += 1
            i += 1
        else:
            out.problems.append(f"record {num}: frames differ: {_describe(mav[i], lua[j])}")
            i += 1
            j += 1
    for frame in lua[j:]:
        if tshark.pymavlink_crc_status(frame) != "ok":
            lua_skipped += 1
        else:
            out.problems.append(
                f"record {num}: CRC-valid frame missing from mavscope: {_describe(None, frame)}"
            )
    out.lua_only += lua_skipped
    lost_sync = record is not None and (
        record.unparsed > 0
        or record.lua_error is not None
        or lua_skipped > 0
        or any(not f.known_msgid for f in lua)
    )
    for obj in mav[i:]:
        if mav_damaged(obj) or lost_sync:
            out.mavscope_only += 1
        else:
            why = "the Lua was not invoked on it" if record is None else "not decoded by the Lua"
            out.problems.append(f"record {num}: mavscope frame {why}: {_describe(obj, None)}")


def crosscheck(capture: Path, run: tshark.TsharkRun, mav: list[dict[str, Any]]) -> Comparison:
    """Compare a whole capture, record by record."""
    by_record: dict[int, list[dict[str, Any]]] = {}
    for obj in mav:
        by_record.setdefault(int(obj["frame"]), []).append(obj)
    out = Comparison()
    for num in sorted(set(by_record) | set(run.records)):
        frames = sorted(by_record.get(num, []), key=lambda o: int(o["index"]))
        if run.cut_short and num > run.last_record:
            out.unread += len(frames)  # tshark does not dissect a record cut short by the end of the file
            continue
        compare_record(num, frames, run.records.get(num), out)
    return out


def assert_agrees(capture: Path, run: tshark.TsharkRun, mav: list[dict[str, Any]]) -> Comparison:
    """Cross-check and fail with the first disagreements; also fail when nothing was compared."""
    result = crosscheck(capture, run, mav)
    shown = "\n".join(result.problems[:25])
    more = f"\n... and {len(result.problems) - 25} more" if len(result.problems) > 25 else ""
    assert not result.problems, (
        f"{capture.name}: mavscope and tshark+Lua disagree ({result.summary()}):\n{shown}{more}\n"
        f"tshark command: {' '.join(run.command)}"
    )
    assert result.full > 0, f"{capture.name}: no frame could be compared ({result.summary()})"
    return result


# ------------------------------------------------------------------------------------ capture tests


def _capture_params() -> list[Any]:
    params = [pytest.param(CAPTURES / name, id=name) for name in GENERATED_UDP_CAPTURES]
    params += [pytest.param(REAL_CAPTURES / name, id=f"real:{name}") for name in REAL_UDP_CAPTURES]
    return params


@pytest.mark.parametrize("capture", _capture_params())
def test_capture_matches_tshark(
    capture: Path, dissect: Callable[[Path], tshark.TsharkRun], record_property: Callable[[str, object], None]
) -> None:
    """Every frame mavscope reports in a UDP capture agrees with tshark + pymavlink's Lua dissector."""
    if not capture.is_file():
        where = (
            "../shared/real-captures is absent" if capture.parent == REAL_CAPTURES else "run `make captures`"
        )
        pytest.skip(f"{capture.name} not available ({where})")
    run = dissect(capture)
    result = assert_agrees(capture, run, mavscope_jsonl(capture))
    record_property("tshark_crosscheck", result.summary())


# ---------------------------------------------------------------------- a synthetic capture of edge cases


@dataclass(frozen=True)
class SyntheticRecord:
    """One datagram of the synthetic capture and what the Lua dissector is expected to do with it."""

    name: str
    data: bytes
    sport: int
    dport: int
    lua_msgids: tuple[int, ...]  # message ids the Lua decodes, in order


def _frames() -> dict[str, bytes]:
    """Deterministic MAVLink frames built with pymavlink (no clock, no randomness)."""
    from pymavlink.dialects.v20 import all as dialect
    from pymavlink.generator.mavcrc import x25crc

    def link(sysid: int, compid: int) -> Any:
        return dialect.MAVLink(None, srcSystem=sysid, srcComponent=compid)

    def recrc(frame: bytearray, extra: int) -> bytes:
        end = len(frame) - 2
        crc = x25crc(bytes(frame[1:end]))
        crc.accumulate(bytes([extra]))
        frame[end:] = crc.crc.to_bytes(2, "little")
        return bytes(frame)

    vehicle, gcs = link(1, 1), link(255, 190)
    hb_extra = dialect.MAVLink_heartbeat_message.crc_extra
    out = {
        "heartbeat": vehicle.heartbeat_encode(2, 12, 0x81, 0, 4).pack(vehicle),
        "attitude": vehicle.attitude_encode(1000, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0).pack(vehicle),
        "rtl": gcs.command_long_encode(1, 1, 20, 0, 0, 0, 0, 0, 0, 0, 0).pack(gcs),
    }
    payload = bytes([0, 0, 0, 0, 2, 12, 0x81, 4, 3])
    header = bytes([0xFE, len(payload), 7, 1, 1, 0])
    out["v1_heartbeat"] = recrc(bytearray(header + payload + b"\0\0"), hb_extra)
    signer = link(1, 1)
    signer.signing.secret_key = b"\x4f" * 32
    signer.signing.sign_outgoing = True
    signer.signing.link_id = 3
    signer.signing.timestamp = 123456789
    out["signed"] = signer.heartbeat_encode(2, 12, 0, 0, 3).pack(signer)
    unknown_flags = bytearray(vehicle.heartbeat_encode(2, 12, 0, 0, 3).pack(vehicle))
    unknown_flags[2] = 0x80
    out["unknown_flags"] = recrc(unknown_flags, hb_extra)
    bad = bytearray(vehicle.heartbeat_encode(2, 12, 0, 0, 3).pack(vehicle))
    bad[-1] ^= 0xFF
    out["bad_crc"] = bytes(bad)
    unknown = bytearray(vehicle.heartbeat_encode(2, 12, 0, 0, 3).pack(vehicle))
    unknown[7:10] = (0xABCDEF).to_bytes(3, "little")
    out["unknown_msgid"] = bytes(unknown)
    out["truncated"] = vehicle.attitude_encode(2000, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0).pack(vehicle)[:-5]
    out["heartbeat2"] = vehicle.heartbeat_encode(2, 12, 0x81, 0, 4).pack(vehicle)
    return out


def synthetic_records() -> list[SyntheticRecord]:
    """The edge cases, one per datagram, with the Lua behaviour documented in docs/testing-tshark.md."""
    f = _frames()
    hb, hb2 = f["heartbeat"], f["heartbeat2"]
    rec, gcs, sitl = SyntheticRecord, (18570, 14550), (14580, 14540)
    return [
        rec("v2 on a registered port", hb, *gcs, (0,)),
        rec("v2 + v1 + signed in one datagram", hb + f["v1_heartbeat"] + f["signed"], *sitl, (0, 0, 0)),
        rec("unregistered ports (decode as)", f["attitude"] + f["rtl"], 14540, 14541, (30, 76)),
        rec("unknown incompat flags decoded as plaintext", f["unknown_flags"] + hb2, *sitl, (0, 0)),
        rec("bad CRC decoded as if good", f["bad_crc"] + hb, *sitl, (0, 0)),
        rec("unknown msgid swallows the rest", f["unknown_msgid"] + hb, *sitl, (0xABCDEF,)),
        rec("garbage between frames stops the Lua", hb + b"\x01\x02\x03" + hb2, *sitl, (0,)),
        rec("one garbage byte at offset 0 is skipped", b"\x07" + hb, *sitl, (0,)),
        rec("two garbage bytes at offset 0 stop the Lua", b"\x07\x07" + hb, *sitl, ()),
        rec("truncated frame at the end", hb + f["truncated"], *sitl, (0, 30)),
        rec("signature cut short", f["signed"][:-5], *sitl, (0,)),
    ]  # fmt: skip


@pytest.fixture(scope="session")
def synthetic_capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A pcap (Ethernet/IPv4/UDP on 127.0.0.1) holding synthetic_records(), with fixed timestamps."""
    from scapy.layers.inet import IP, UDP
    from scapy.layers.l2 import Ether
    from scapy.packet import Raw
    from scapy.utils import wrpcap

    packets = []
    for n, rec in enumerate(synthetic_records()):
        pkt = (
            Ether(src="02:00:00:00:00:01", dst="02:00:00:00:00:02")
            / IP(src="127.0.0.1", dst="127.0.0.1", id=n + 1)
            / UDP(sport=rec.sport, dport=rec.dport)
            / Raw(rec.data)
        )
        pkt.time = 1_700_000_000 + n / 10
        packets.append(pkt)
    path = tmp_path_factory.mktemp("synthetic") / "synthetic_udp.pcap"
    wrpcap(str(path), packets)
    return path


def test_lua_dissector_behaviour(
    synthetic_capture: Path, dissect: Callable[[Path], tshark.TsharkRun]
) -> None:
    """The Lua dissector decodes the synthetic edge cases the way docs/testing-tshark.md says."""
    run = dissect(synthetic_capture)
    for num, rec in enumerate(synthetic_records(), start=1):
        got = tuple(f.msgid for f in run.records[num].frames) if num in run.records else ()
        assert got == rec.lua_msgids, f"record {num} ({rec.name}): Lua decoded msgids {got}"
    frames = {num: r.frames for num, r in run.records.items()}
    v1, signed = frames[2][1], frames[2][2]
    assert (v1.magic, v1.incompat_flags, v1.seq) == (0xFE, None, 7)
    assert (signed.link_id, signed.sig_timestamp) == (3, 123456789)
    assert frames[4][0].incompat_flags == 0x80 and frames[4][0].known_msgid
    assert tshark.pymavlink_crc_status(frames[5][0]) == "bad"  # decoded anyway: no CRC check
    assert not frames[6][0].known_msgid and frames[6][0].payload.endswith(_frames()["heartbeat"][:-2])
    assert run.records[7].unparsed == 1
    assert tshark.pymavlink_crc_status(frames[10][1]) == "unchecked"
    assert frames[11][0].incompat_flags == 1 and not frames[11][0].signed  # signature silently dropped


def test_synthetic_capture_matches_tshark(
    synthetic_capture: Path, dissect: Callable[[Path], tshark.TsharkRun]
) -> None:
    """mavscope agrees with the Lua dissector on the synthetic edge cases, under the damage rules."""
    assert_agrees(synthetic_capture, dissect(synthetic_capture), mavscope_jsonl(synthetic_capture))


def _as_mavscope(frame: tshark.LuaFrame) -> dict[str, Any]:
    """A mavscope-shaped JSON object mirroring a Lua frame, with pymavlink's CRC verdict."""
    return {
        "frame": frame.frame,
        "index": frame.order,
        "version": frame.version,
        "len": frame.length,
        "incompat_flags": frame.incompat_flags if frame.version == 2 else 0,
        "compat_flags": frame.compat_flags if frame.version == 2 else 0,
        "seq": frame.seq,
        "sysid": frame.sysid,
        "compid": frame.compid,
        "msgid": frame.msgid,
        "crc": frame.crc,
        "crc_status": tshark.pymavlink_crc_status(frame),
        "signature": {"link_id": frame.link_id, "timestamp": frame.sig_timestamp} if frame.signed else None,
        "notes": [],
    }


def test_comparison_catches_disagreements(
    synthetic_capture: Path, dissect: Callable[[Path], tshark.TsharkRun]
) -> None:
    """The comparison itself: a faithful mirror of the Lua's frames agrees; each kind of error is caught."""
    run = dissect(synthetic_capture)
    faithful = [_as_mavscope(f) for f in run.frames()]
    assert not crosscheck(synthetic_capture, run, faithful).problems

    def problems_after(mutate: Callable[[list[dict[str, Any]]], None]) -> list[str]:
        copy = [dict(o) for o in faithful]
        mutate(copy)
        return crosscheck(synthetic_capture, run, copy).problems

    signed_at = next(i for i, o in enumerate(faithful) if o["signature"])
    assert problems_after(lambda m: m[0].update(sysid=42))
    assert problems_after(lambda m: m[0].update(crc=0))
    assert problems_after(lambda m: m.pop(0))
    assert problems_after(lambda m: m[signed_at].update(signature={"link_id": 3, "timestamp": 1}))
    assert problems_after(lambda m: m[signed_at].update(signature=None))
    assert problems_after(lambda m: m[1].update(crc_status="bad"))  # pymavlink says the CRC is good
    bad_at = next(i for i, o in enumerate(faithful) if o["crc_status"] == "bad")
    assert problems_after(lambda m: m[bad_at].update(crc_status="ok"))  # pymavlink says the CRC is bad
