"""The fuzz targets: one function per layer, each taking arbitrary bytes (see tests/fuzz/__init__.py)."""

from __future__ import annotations

import os
import re
import struct
import sys
import tempfile
from collections.abc import Callable

import atheris

with atheris.instrument_imports():
    from mavscope.analysis.command_log import reconstruct as command_log
    from mavscope.analysis.events.log import story
    from mavscope.analysis.expert import expert_findings
    from mavscope.analysis.mission.export import log_json
    from mavscope.analysis.mission.reconstruct import analyse as mission
    from mavscope.analysis.objects.tracker import analyse as objects
    from mavscope.analysis.params.export import params_json
    from mavscope.analysis.params.tracker import analyse as params
    from mavscope.analysis.stats import compute_stats
    from mavscope.analysis.timeline import reconstruct as timeline
    from mavscope.analysis.track import tracks
    from mavscope.capture.detect import open_capture
    from mavscope.endpoint import Endpoint
    from mavscope.errors import MavscopeError
    from mavscope.export.source import record_batches  # noqa: F401  (instrumented before the comparison imports it)
    from mavscope.fields.summary import summary_info
    from mavscope.fields.tree import frame_items
    from mavscope.filter import compile_filter
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.mavlink.framing import mcrf4xx
    from mavscope.native import export as native_export
    from mavscope.output.jsonout import jsonl_bytes
    from mavscope.pipeline.dissect import Anomaly, Dissector
    from mavscope.pipeline.options import PipelineOptions
    from mavscope.pipeline.session import make_security_stage
    from mavscope.security.audit import audit
    from mavscope.transport.tcp import TcpReassembler

from tests.support.sources import same_tables

DIALECT = load_dialect()
SECURITY = PipelineOptions(keys=("passphrase:mavscope-demo",), ciphers=("2=aes-128-ctr:hex:" + "00" * 16,),
                           ecdh_private=("hex:" + "11" * 32,), wifi_keys=("wpa-pwd:drone-pass-2024:ArduPilotNet",))
SUFFIXES = (".pcap", ".pcapng", ".tlog", ".raw")  # content decides the reader; the name does not


def capture(data: bytes) -> None:
    """A capture file of any content, through the whole pipeline and every rendering of every frame."""
    fd, path = tempfile.mkstemp(suffix=SUFFIXES[len(data) % 4])
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        with open_capture(path) as reader:
            stage = make_security_stage(SECURITY)
            for item in stage.run(Dissector(DIALECT, stage.material.wifi).run(reader)):
                if type(item) is Anomaly:
                    continue
                jsonl_bytes(item)
                summary_info(item, DIALECT)
                frame_items(item, DIALECT)
    finally:
        os.unlink(path)


A, B = Endpoint("10.0.0.1", 5760), Endpoint("10.0.0.2", 40000)


def tcp(data: bytes) -> None:
    """Segments (direction, flags, sequence number, length-prefixed payload) into the reassembler."""
    r = TcpReassembler(max_buffered=1 << 16)
    pos, record = 0, 0
    while pos + 8 <= len(data):
        direction, flags, seq, n = struct.unpack_from("<BBIH", data, pos)
        pos += 8
        payload = data[pos : pos + n]
        pos += n
        record += 1
        src, dst = (A, B) if direction & 1 else (B, A)
        r.segment(src, dst, seq, flags, payload, record, pos)
    r.flush()


SAMPLE = []


def _sample_frames() -> list:
    if not SAMPLE:
        root = os.path.join(os.path.dirname(__file__), "..", "..", "captures")
        for name in ("px4_sitl_udp.pcap", "signed_udp.pcap", "damaged.pcap"):
            with open_capture(os.path.join(root, name)) as reader:
                SAMPLE.extend(f for f in Dissector(DIALECT).run(reader) if type(f) is not Anomaly)
    return SAMPLE[::23]


def display_filter(data: bytes) -> None:
    """Filter text of any content: it compiles or is a FilterError (a MavscopeError); what compiles runs."""
    text = data.decode("utf-8", "replace")
    try:
        flt = compile_filter(text, DIALECT)
    except MavscopeError:
        return
    for f in _sample_frames():
        flt.matches(f)


SECRET = "Zq7secretQ"


_NAMED = re.compile(r"(?:([A-Za-z0-9_.@-]{1,64})=)?(?:hex|base64|passphrase|qgc|(file)):")


def _public(spec: str, message: str) -> str:
    """`message` without the parts of a `--key` spec that are no secret and that a message may name: the
    key's NAME (`NAME=hex:...`) and a keyring's path (`file:PATH`)."""
    m = _NAMED.match(spec)
    if m is None:
        return message
    if m.group(2):  # a keyring: the message is about the file the user named (its entries: test_hostile_keys)
        return ""
    return message.replace(m.group(1), "NAME") if m.group(1) else message


def key_spec(data: bytes) -> None:
    """A key spec of any shape around a known secret: accepted, or refused without a trace of the secret."""
    text = data.decode("utf-8", "replace")
    for spec in (text, text + SECRET, SECRET + text, text.replace("#", SECRET)):
        for option in ("keys", "ciphers", "ecdh_private"):
            try:
                make_security_stage(PipelineOptions(**{option: (spec,)}))
            except MavscopeError as exc:
                message = _public(spec, str(exc)) if option == "keys" else str(exc)
                assert SECRET not in message, f"{option} {spec!r}: {exc}"


# The messages the analyses read (stats, expert, commands, mission, timeline, objects, params, events,
# track, audit): most frames of the `analyses` target are one of these, the rest any message of the dialect.
ANALYSED = (
    "HEARTBEAT", "COMMAND_LONG", "COMMAND_INT", "COMMAND_ACK", "MISSION_COUNT", "MISSION_REQUEST_INT",
    "MISSION_REQUEST", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK", "MISSION_CLEAR_ALL", "MISSION_CURRENT",
    "MISSION_ITEM_REACHED", "MISSION_SET_CURRENT", "PARAM_VALUE", "PARAM_SET", "PARAM_EXT_VALUE", "PARAM_EXT_SET",
    "PARAM_EXT_ACK", "FILE_TRANSFER_PROTOCOL", "LOG_ENTRY", "LOG_REQUEST_DATA", "LOG_DATA", "LOG_REQUEST_END",
    "DATA_TRANSMISSION_HANDSHAKE", "ENCAPSULATED_DATA", "GLOBAL_POSITION_INT", "GPS_RAW_INT", "SYSTEM_TIME",
    "TIMESYNC", "PING", "STATUSTEXT", "MANUAL_CONTROL", "RC_CHANNELS_OVERRIDE", "SET_MODE", "EXTENDED_SYS_STATE",
    "EKF_STATUS_REPORT", "AUTOPILOT_VERSION", "SETUP_SIGNING", "REQUEST_DATA_STREAM", "HOME_POSITION",
)
_BY_NAME = {md.name: md for md in DIALECT.messages.values()}
_ANALYSED = [_BY_NAME[n] for n in ANALYSED if n in _BY_NAME]
_ALL = sorted(DIALECT.messages.values(), key=lambda md: md.id)


def _frames(data: bytes) -> bytes:
    """A tlog of up to 96 MAVLink 2 frames with good CRCs, whose senders, messages, payload bytes and times
    (forward, still, or back: a reboot) the input chooses: the analyses see frames the pipeline accepts."""
    fdp = atheris.FuzzedDataProvider(data)
    out, t, seqs = bytearray(), 1_700_000_000_000_000, [0] * 256
    for _ in range(96):
        if fdp.remaining_bytes() < 4:
            break
        t = max(0, t + fdp.ConsumeIntInRange(-2_000_000, 30_000_000))
        sysid = fdp.PickValueInList([1, 1, 1, 255, 255, 42, 2, fdp.ConsumeIntInRange(0, 255)])
        compid = fdp.PickValueInList([1, 190, 0, 230, fdp.ConsumeIntInRange(0, 255)])
        md = fdp.PickValueInList(_ANALYSED) if fdp.ConsumeIntInRange(0, 7) else fdp.PickValueInList(_ALL)
        payload = fdp.ConsumeBytes(md.length)
        seqs[sysid] = (seqs[sysid] + fdp.PickValueInList([1, 1, 1, 0, 2, 200])) & 0xFF
        body = struct.pack("<BBBBBB", len(payload), 0, 0, seqs[sysid], sysid, compid) + md.id.to_bytes(3, "little")
        body += payload
        crc = mcrf4xx(md.crc_extra_byte, mcrf4xx(body))
        out += struct.pack(">Q", t) + b"\xfd" + body + struct.pack("<H", crc)
    return bytes(out)


def analyses(data: bytes) -> None:
    """Frames the pipeline accepts, of the messages the analyses read, with fuzzed payloads and times:
    every analysis and its JSON over them (a crafted payload must never raise in an analysis)."""
    fd, path = tempfile.mkstemp(suffix=".tlog")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(_frames(data))
        with open_capture(path) as reader:
            frames = [f for f in make_security_stage(PipelineOptions()).run(Dissector(DIALECT).run(reader))
                      if type(f) is not Anomaly]
    finally:
        os.unlink(path)
    compute_stats(frames).to_json()
    expert_findings(frames, DIALECT)
    command_log(frames, DIALECT)
    timeline(frames).to_json()
    log_json(mission(frames, DIALECT), DIALECT)
    objects(frames, DIALECT)
    params_json(params(frames))
    story(frames, DIALECT).to_json()
    tracks(frames, DIALECT)
    audit(frames)


EXPORT_KEYS = (PipelineOptions(), PipelineOptions(keys=("passphrase:mavscope-demo",)),
               PipelineOptions(use_leaked_keys=True))


def export(data: bytes) -> None:
    """A capture file of any content into the dataset's tables by every batch source: each gives the
    pure-Python source's schemas and rows (tests/support/sources.py). The first byte picks the keys, the
    native source's window (whole, or 7 frames so handed-back frames fall inside and between windows) and
    the batch size."""
    if not data or native_export._native is None:
        return
    mode, body = data[0], data[1:]
    saved = native_export.WINDOW_FRAMES
    fd, path = tempfile.mkstemp(suffix=".cap")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(body)
        if mode & 4:
            native_export.WINDOW_FRAMES = 7
        same_tables(path, EXPORT_KEYS[mode % 3], rows=5 if mode & 8 else 65_536)
    finally:
        native_export.WINDOW_FRAMES = saved
        os.unlink(path)


TARGETS: dict[str, Callable[[bytes], None]] = {
    "capture": capture, "tcp": tcp, "filter": display_filter, "keys": key_spec, "analyses": analyses,
    "export": export,
}


def main() -> None:
    name = sys.argv.pop(1)
    atheris.Setup(sys.argv, TARGETS[name])
    atheris.Fuzz()


if __name__ == "__main__":
    main()
