"""Text presentation: tshark-like summary lines, the -V detail tree and the -x hex dump."""

from __future__ import annotations

from mavscope.fields.summary import frame_heading, summary_info
from mavscope.fields.tree import Item, frame_items
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame


def summary_line(frame: Frame, dialect: Dialect, t0: float | None, fields: dict[str, object] | None = None,
                 time_text: str | None = None) -> str:
    """One tshark-like line: number, time (relative to `t0`, or `time_text`: read -t's column), src -> dst,
    sysid/compid, seq, info."""
    if time_text is not None:
        t = time_text
    elif frame.time is not None and t0 is not None:
        t = f"{frame.time - t0:11.6f}"
    else:
        t = f"{'-':>11}"
    num = frame.number
    route = f"{frame.src or frame.transport} → {frame.dst or ''}".rstrip(" →") if frame.src else frame.transport
    return (
        f"{num:>7} {t} {route:<34} {frame.sysid:>3}/{frame.compid:<3} "
        f"v{frame.version} seq {frame.seq:>3} {summary_info(frame, dialect, fields)}"
    )


def tree_lines(items: tuple[Item, ...], indent: int = 0) -> list[str]:
    """The -V detail tree as indented lines."""
    out: list[str] = []
    for it in items:
        out.append("    " * indent + it.label)
        out.extend(tree_lines(it.children, indent + 1))
    return out


def detail_text(frame: Frame, dialect: Dialect) -> str:
    """Everything -V shows for a frame."""
    return "\n".join([frame_heading(frame), *tree_lines(frame_items(frame, dialect), 1)])


def hexdump(data: bytes, width: int = 16) -> str:
    """Classic hex dump: offset, hex bytes, ASCII."""
    lines = []
    for off in range(0, len(data), width):
        chunk = data[off : off + width]
        hexpart = " ".join(f"{b:02x}" for b in chunk)
        if len(chunk) > 8:
            hexpart = hexpart[:23] + " " + hexpart[23:]
        asc = "".join(chr(b) if 32 <= b < 127 else "." for b in chunk)
        lines.append(f"{off:04x}  {hexpart:<{width * 3 + 1}} {asc}")
    return "\n".join(lines)


