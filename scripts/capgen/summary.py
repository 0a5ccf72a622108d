"""expected.json: what a correct decoder must report per capture, computed from what was generated
(never by decoding), and written one frame per line so that a change to a capture shows in a diff."""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from typing import Any

from .frames import Frame
from .packets import Pkt


def summarize(fmt: str, linktypes: list[int], records: int | None,
              located: Iterable[tuple[int | None, int, int, Frame]],
              truncated: Sequence[tuple[int | None, int]], skipped: int) -> dict[str, Any]:
    """Counts and lists from (record, index in record, file offset of STX, frame) per frame and
    (record, file offset of STX) per truncated frame."""
    rows = list(located)
    frames = [f for _, _, _, f in rows]
    return {
        "format": fmt,
        "linktypes": linktypes,
        "records": records,
        "frames": len(frames),
        "crc_ok": sum(f.crc == "ok" for f in frames),
        "crc_bad": sum(f.crc == "bad" for f in frames),
        "crc_unchecked": sum(f.crc == "unchecked" for f in frames),
        "v1": sum(f.version == 1 for f in frames),
        "v2": sum(f.version == 2 for f in frames),
        "signed": sum(f.signed for f in frames),
        "truncated": len(truncated),
        "skipped_bytes": skipped,
        "frame_list": [[rec, idx, f.sysid, f.compid, f.seq, f.msgid] for rec, idx, _, f in rows],
        "frame_offsets": [off for _, _, off, _ in rows],
        "frame_crc": [f.crc for f in frames],
        "truncated_list": [list(t) for t in truncated],
    }


def summarize_packets(fmt: str, linktypes: list[int], pkts: Sequence[Pkt], offsets: Sequence[int]) -> dict[str, Any]:
    """`summarize` for a packet capture: records numbered from 1, frame offsets in the file."""
    located, cuts = [], []
    for number, (p, data_off) in enumerate(zip(pkts, offsets), start=1):
        for idx, (off, fr) in enumerate(p.frames, start=1):
            located.append((number, idx, data_off + p.payload_at + off, fr))
        cuts += [(number, data_off + p.payload_at + off) for off in p.cuts]
    return summarize(fmt, linktypes, len(pkts), located, cuts, sum(p.skipped for p in pkts))


def dump_expected(expected: dict[str, Any]) -> str:
    """JSON with one frame per line: readable and diff-friendly."""
    lines = ["{"]
    for n, (name, entry) in enumerate(expected.items()):
        lines.append(f"  {json.dumps(name)}: {{")
        items = list(entry.items())
        for i, (key, value) in enumerate(items):
            comma = "," if i < len(items) - 1 else ""
            if key.startswith("frame_") or key == "cases":
                inner = ",\n".join(f"      {json.dumps(v)}" for v in value)
                body = f"[\n{inner}\n    ]" if value else "[]"
                lines.append(f"    {json.dumps(key)}: {body}{comma}")
            else:
                lines.append(f"    {json.dumps(key)}: {json.dumps(value)}{comma}")
        lines.append("  }" + ("," if n < len(expected) - 1 else ""))
    lines.append("}")
    return "\n".join(lines) + "\n"
