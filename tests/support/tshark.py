"""Run tshark with pymavlink's generated Wireshark Lua dissector and read back every MAVLink frame.

This is the reference side of ``tests/test_tshark_crosscheck.py``. It

1. generates the Lua dissector with pymavlink's own generator
   (``python -m pymavlink.tools.mavgen --lang=WLua --wire-protocol=2.0`` on ``dialects/v20/all.xml``),
2. runs ONE ``tshark`` process per capture with ``-X lua_script:<file> -T pdml``, forcing the
   dissector onto UDP ports it does not register itself (``-d udp.port==N,mavlink_proto``),
3. parses the PDML into one :class:`LuaFrame` per MAVLink frame the Lua dissector decoded, in the
   order it decoded them within each capture record.

PDML rather than ``-T fields``: the Lua dissector adds one ``mavlink_proto`` subtree per frame and
datagrams hold several frames; ``-T fields`` flattens each field's occurrences into one list per record,
and because v1 frames have no flag fields and unsigned frames no signature fields, those lists cannot be
zipped back into frames. PDML keeps the per-frame subtrees, each field's raw bytes (``value``) and its
byte position (``pos``). See ``docs/testing-tshark.md`` for the dissector's quirks.

Nothing here imports mavscope: this module is the independent side of the comparison.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import pymavlink

# UDP and TCP ports the generated Lua registers itself on (see generate_epilog in
# pymavlink/generator/mavgen_wlua.py). Any other port needs a "decode as" on the command line.
LUA_UDP_PORTS: frozenset[int] = frozenset({14550, 14580, 18570})
LUA_TCP_PORTS: frozenset[int] = frozenset(range(5760, 5764))

LUA_PROTO = "mavlink_proto"  # the Proto() name: filter prefix and the name "-d ...,<proto>" takes
MAGIC_V1 = 0xFE
MAGIC_V2 = 0xFD
SIGNATURE_LEN = 13

# Seconds one tshark run may take before it is treated as hung.
TSHARK_TIMEOUT_S = 300


class TsharkUnavailable(RuntimeError):
    """tshark is not installed, has no Lua support, or cannot load the generated dissector.

    Tests turn this into ``pytest.skip(str(exc))``: a missing optional tool never fails CI.
    """


@dataclass(frozen=True, slots=True)
class LuaFrame:
    """One MAVLink frame as pymavlink's Wireshark Lua dissector decoded it.

    Integers are decoded from the raw bytes tshark reports for each field (PDML ``value``), not from
    its display strings, so they do not depend on display bases or the machine's time zone.
    """

    frame: int  # capture record number (tshark frame.number, 1-based)
    order: int  # 1-based position of this frame among the frames the Lua decoded in the record
    pos: int  # byte offset of the magic byte within the record (link-layer header included)
    magic: int  # 0xFE (v1) or 0xFD (v2)
    length: int  # payload length byte as on the wire
    incompat_flags: int | None  # None for v1
    compat_flags: int | None  # None for v1
    seq: int
    sysid: int
    compid: int
    msgid: int
    known_msgid: bool  # False: the Lua had no payload dissector and swallowed the rest of the record
    payload: bytes  # the bytes the Lua took as payload (the rest of the record when known_msgid is False)
    crc: int | None  # the two bytes after the payload, little-endian; None when the Lua added none
    link_id: int | None  # signature link id; None when no signature was dissected
    sig_timestamp: int | None  # signature timestamp in 10 us units since 2015-01-01; None as above
    header_bytes: bytes = field(repr=False, default=b"")  # magic..msgid as on the wire

    @property
    def version(self) -> int:
        """MAVLink major version implied by the magic byte (1 or 2)."""
        return 1 if self.magic == MAGIC_V1 else 2

    @property
    def signed(self) -> bool:
        """True when the Lua dissected a signature block for this frame."""
        return self.link_id is not None


@dataclass(frozen=True, slots=True)
class LuaRecord:
    """What the Lua dissector did with one capture record that it was invoked on."""

    frame: int  # capture record number
    frames: tuple[LuaFrame, ...]  # decoded frames, in order
    unparsed: int  # subtrees without a header: garbage ("Unknown message") or a truncated header
    lua_error: str | None  # text of a Lua runtime error, if the dissector raised one on this record


@dataclass(frozen=True, slots=True)
class TsharkRun:
    """The result of dissecting one capture: records keyed by frame number, plus how it was run."""

    capture: Path
    records: dict[int, LuaRecord]  # only records the Lua dissector was invoked on
    command: tuple[str, ...]
    last_record: int  # number of the last capture record tshark read
    cut_short: bool  # tshark stopped at a last record cut short by the end of the file (and skipped it)

    def frames(self) -> Iterator[LuaFrame]:
        """Every decoded frame, in capture order."""
        for num in sorted(self.records):
            yield from self.records[num].frames


def find_tshark() -> str:
    """Path of a tshark built with Lua support; TsharkUnavailable with the reason otherwise."""
    exe = shutil.which("tshark")
    if exe is None:
        raise TsharkUnavailable("tshark is not on PATH (install it with scripts/install-test-tools.sh)")
    try:
        out = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=60, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise TsharkUnavailable(f"tshark --version failed: {exc}") from exc
    if out.returncode != 0:
        raise TsharkUnavailable(f"tshark --version exited {out.returncode}: {out.stderr.strip()[:200]}")
    if "Lua" not in out.stdout:
        raise TsharkUnavailable("this tshark was built without Lua support")
    return exe


def tshark_version(exe: str) -> str:
    """First line of ``tshark --version``, e.g. 'TShark (Wireshark) 4.0.17 (...)'."""
    out = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=60, check=False)
    return out.stdout.splitlines()[0] if out.stdout else "unknown"


def dialect_xml(name: str = "all") -> Path:
    """Path of one of pymavlink's bundled v2 dialect XML files (``all`` includes every dialect)."""
    path = Path(pymavlink.__file__).parent / "dialects" / "v20" / f"{name}.xml"
    if not path.is_file():
        raise FileNotFoundError(f"pymavlink ships no {path}")
    return path


def generate_lua_dissector(out_dir: Path, dialect: str = "all") -> Path:
    """Generate pymavlink's Wireshark Lua dissector for ``dialect`` into ``out_dir``; return its path.

    Runs ``python -m pymavlink.tools.mavgen --lang=WLua --wire-protocol=2.0`` in a subprocess
    (the generator prints progress to stdout and calls exit() on validation errors).
    Raises TsharkUnavailable when generation fails.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    lua = out_dir / f"mavlink_{dialect}.lua"
    cmd = [
        sys.executable, "-m", "pymavlink.tools.mavgen",
        "--lang=WLua", "--wire-protocol=2.0", f"--output={lua}", str(dialect_xml(dialect)),
    ]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False, cwd=out_dir)
    if proc.returncode != 0 or not lua.is_file():
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        raise TsharkUnavailable(f"mavgen --lang=WLua failed ({proc.returncode}): {' | '.join(tail)}")
    return lua


def check_lua_loads(exe: str, lua: Path) -> None:
    """Make sure tshark can load ``lua`` and knows the mavlink_proto protocol (TsharkUnavailable if not).

    ``tshark -G protocols`` (``-G`` must come first) lists registered protocols as
    "name<TAB>short name<TAB>filter name"; a Lua script that fails to load leaves
    mavlink_proto out and prints the Lua error on stderr.
    """
    proc = subprocess.run(
        [exe, "-G", "protocols", "-X", f"lua_script:{lua}"],
        capture_output=True, text=True, timeout=TSHARK_TIMEOUT_S, check=False, env=_tshark_env(lua.parent),
    )  # fmt: skip
    registered = any(line.split("\t")[-1] == LUA_PROTO for line in proc.stdout.splitlines())
    if proc.returncode != 0 or not registered:
        err = " | ".join(line for line in proc.stderr.splitlines() if "Running as user" not in line)
        raise TsharkUnavailable(
            f"tshark did not load the generated Lua dissector: {err[:300] or 'no error text'}"
        )


def _tshark_env(work_dir: Path) -> dict[str, str]:
    """Environment for tshark: an empty configuration dir of its own (under ``work_dir``) so the
    preferences, profiles, personal Lua plugins and "decode as" entries of whoever runs the tests cannot
    change the result; UTC so nothing time-zone dependent leaks in."""
    conf = work_dir / "wireshark-config"
    conf.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    env["WIRESHARK_CONFIG_DIR"] = str(conf)
    env["TZ"] = "UTC"
    env.setdefault("LC_ALL", "C.UTF-8")
    return env


def mavlink_udp_ports(capture: Path) -> set[int]:
    """UDP ports of flows in ``capture`` that carry datagrams starting with a MAVLink magic byte.

    Used to "decode as" MAVLink on ports the Lua does not register (PX4 SITL's 14540, say).
    Reads the capture with scapy (pcap or pcapng, any link type scapy decodes).
    """
    from scapy.layers.inet import UDP
    from scapy.utils import PcapReader

    ports: set[int] = set()
    with PcapReader(str(capture)) as reader:
        for pkt in reader:
            udp = pkt.getlayer(UDP)
            if udp is None:
                continue
            data = bytes(udp.payload)
            if data[:1] in (b"\xfd", b"\xfe"):
                ports.update((int(udp.sport), int(udp.dport)))
    return ports


def tshark_command(exe: str, lua: Path, capture: Path, udp_ports: Iterable[int] = ()) -> list[str]:
    """The tshark command line that dissects ``capture`` with ``lua`` and prints PDML.

    ``-J mavlink_proto`` keeps only the MAVLink subtrees (plus PDML's always-present ``geninfo`` with
    the frame number, so every record read shows up); each extra UDP port gets
    ``-d udp.port==N,mavlink_proto``.
    """
    cmd = [exe, "-n", "-X", f"lua_script:{lua}", "-r", str(capture)]
    for port in sorted(set(udp_ports) - LUA_UDP_PORTS):
        cmd += ["-d", f"udp.port=={port},{LUA_PROTO}"]
    cmd += ["-T", "pdml", "-J", LUA_PROTO]
    return cmd


def run_lua_dissector(
    exe: str, lua: Path, capture: Path, udp_ports: Iterable[int] | None = None
) -> TsharkRun:
    """Dissect ``capture`` with one tshark process and return every MAVLink frame the Lua decoded.

    ``udp_ports``: ports to force the dissector onto; by default those found by mavlink_udp_ports().
    Raises TsharkUnavailable when tshark fails to run or its output is not PDML.
    """
    ports = mavlink_udp_ports(capture) if udp_ports is None else set(udp_ports)
    cmd = tshark_command(exe, lua, capture, ports)
    try:
        proc = subprocess.run(
            cmd, capture_output=True, timeout=TSHARK_TIMEOUT_S, check=False, env=_tshark_env(lua.parent)
        )
    except subprocess.TimeoutExpired as exc:
        raise TsharkUnavailable(f"tshark took over {TSHARK_TIMEOUT_S}s on {capture.name}") from exc
    err = [
        line for line in proc.stderr.decode(errors="replace").splitlines() if "Running as user" not in line
    ]
    # tshark exits 2 when the last record is cut short by the end of the file; it has then printed
    # every complete record (and closed the PDML), so the run is usable.
    cut_short = proc.returncode == 2 and any("cut short in the middle of a packet" in line for line in err)
    if proc.returncode != 0 and not cut_short:
        raise TsharkUnavailable(f"tshark exited {proc.returncode} on {capture.name}: {' | '.join(err)[:300]}")
    try:
        records, last = parse_pdml(proc.stdout)
    except ET.ParseError as exc:
        raise TsharkUnavailable(f"tshark output for {capture.name} is not valid PDML: {exc}") from exc
    return TsharkRun(
        capture=capture, records=records, command=tuple(cmd), last_record=last, cut_short=cut_short
    )


def _raw(elem: ET.Element) -> bytes:
    """The raw bytes PDML reports for a field (its hex ``value`` attribute)."""
    return bytes.fromhex(elem.get("value", ""))


def _le(elem: ET.Element) -> int:
    """A field's raw bytes read as a little-endian unsigned integer."""
    return int.from_bytes(_raw(elem), "little")


def parse_pdml(pdml: bytes) -> tuple[dict[int, LuaRecord], int]:
    """Turn tshark's PDML output into LuaRecords keyed by capture record number.

    Returns the records the Lua dissector was invoked on and the number of the last record read.
    """
    root = ET.fromstring(pdml)
    records: dict[int, LuaRecord] = {}
    last = 0
    for packet in root.iter("packet"):
        num_field = packet.find("proto[@name='geninfo']/field[@name='num']")
        if num_field is None:
            continue
        num = int(num_field.get("show", "0"))
        last = max(last, num)
        if packet.find(f"proto[@name='{LUA_PROTO}']") is None:
            continue
        frames: list[LuaFrame] = []
        unparsed = 0
        lua_error: str | None = None
        for proto in packet.iter("proto"):
            if proto.get("name") != LUA_PROTO:
                continue
            frame = _parse_subtree(proto, num, len(frames) + 1)
            if frame is None:
                unparsed += 1
            else:
                frames.append(frame)
        # A Lua runtime error shows up as a text item "Lua Error: <file>:<line>: <message>" that
        # Wireshark puts outside the mavlink_proto subtree (in the "fake-field-wrapper" proto).
        for elem in packet.iter("field"):
            text = elem.get("show") or ""
            if text.startswith("Lua Error"):
                lua_error = text
                break
        records[num] = LuaRecord(frame=num, frames=tuple(frames), unparsed=unparsed, lua_error=lua_error)
    return records, last


def _parse_subtree(proto: ET.Element, num: int, order: int) -> LuaFrame | None:
    """One ``mavlink_proto`` subtree as a LuaFrame, or None when it holds no complete header."""
    by_name: dict[str, ET.Element] = {}
    for elem in proto.iter("field"):
        name = elem.get("name", "")
        if name.startswith(LUA_PROTO + ".") and name not in by_name:
            by_name[name.removeprefix(LUA_PROTO + ".")] = elem
    magic_elem = by_name.get("magic")
    if magic_elem is None or "msgid" not in by_name:
        return None
    magic = _le(magic_elem)
    v2 = magic == MAGIC_V2
    header_names = (
        (
            "magic",
            "length",
            "incompatibility_flag",
            "compatibility_flag",
            "sequence",
            "sysid",
            "compid",
            "msgid",
        )
        if v2
        else ("magic", "length", "sequence", "sysid", "compid", "msgid")
    )
    header = b"".join(_raw(by_name[n]) for n in header_names)
    payload_elem = by_name.get("payload")
    known = payload_elem is not None
    if payload_elem is None:
        payload_elem = by_name.get("rawpayload")
    payload = _raw(payload_elem) if payload_elem is not None else b""
    crc_elem = by_name.get("crc")
    link = by_name.get("signature_link")
    ts = by_name.get("signature_time")
    return LuaFrame(
        frame=num,
        order=order,
        pos=int(magic_elem.get("pos", "0")),
        magic=magic,
        length=_le(by_name["length"]),
        incompat_flags=_le(by_name["incompatibility_flag"]) if v2 else None,
        compat_flags=_le(by_name["compatibility_flag"]) if v2 else None,
        seq=_le(by_name["sequence"]),
        sysid=_le(by_name["sysid"]),
        compid=_le(by_name["compid"]),
        msgid=_le(by_name["msgid"]),
        known_msgid=known,
        payload=payload,
        crc=_le(crc_elem) if crc_elem is not None and len(_raw(crc_elem)) == 2 else None,
        link_id=_le(link) if link is not None else None,
        sig_timestamp=_le(ts) if ts is not None else None,
        header_bytes=header,
    )


@cache
def _crc_extras() -> dict[int, int]:
    """msgid -> CRC_EXTRA from pymavlink's generated ``all`` dialect (the same XML the Lua is built from)."""
    from pymavlink.dialects.v20 import all as dialect

    return {msgid: int(cls.crc_extra) for msgid, cls in dialect.mavlink_map.items()}


def pymavlink_crc_status(frame: LuaFrame) -> str:
    """Check a Lua-decoded frame's CRC with pymavlink, the independent oracle the Lua lacks.

    Returns "ok", "bad", or "unchecked" (message id unknown to pymavlink's ``all`` dialect, or the
    Lua did not isolate the frame's payload/CRC: unknown msgid to the Lua, or fewer payload bytes than
    the length byte says, i.e. a truncated frame).
    """
    from pymavlink.generator.mavcrc import x25crc

    extra = _crc_extras().get(frame.msgid)
    if extra is None or not frame.known_msgid or frame.crc is None or len(frame.payload) != frame.length:
        return "unchecked"
    crc = x25crc(frame.header_bytes[1:] + frame.payload)
    crc.accumulate(bytes([extra]))
    return "ok" if crc.crc == frame.crc else "bad"
