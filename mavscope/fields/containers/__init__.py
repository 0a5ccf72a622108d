"""Dissectors of the protocols MAVLink messages carry in their byte arrays (Wireshark's subdissectors).

`SPECS` declares every container field once (the registry registers them: `ftp.*`, `log.*`,
`tunnel.*`, `serial.*`, `encap.*`); `subtree(frame, fd)` gives, for a payload field that is a
container, the summary its tree line shows and the nodes nested under it, each with its byte range in
the frame. Per frame and stateless; never raises on any byte pattern.
"""

from __future__ import annotations

from collections.abc import Callable

from mavscope.fields.containers import ftp, others
from mavscope.fields.containers.base import Node, Spec
from mavscope.mavlink.dialect import FieldDef
from mavscope.mavlink.frame import Frame

SPECS: tuple[Spec, ...] = ftp.SPECS + others.SPECS

# (message, payload field) -> its dissector
_SUBTREES: dict[tuple[str, str], Callable[[Frame], tuple[str, tuple[Node, ...]] | None]] = {
    (ftp.MESSAGE, "payload"): ftp.subtree,
    ("LOG_DATA", "data"): others.log_subtree,
    ("TUNNEL", "payload"): others.tunnel_subtree,
    ("SERIAL_CONTROL", "data"): others.serial_subtree,
    ("ENCAPSULATED_DATA", "data"): others.encap_subtree,
}


def subtree(frame: Frame, fd: FieldDef) -> tuple[str, tuple[Node, ...]] | None:
    """For a container payload field of `frame`: (summary of its line, the nodes under it); else None."""
    dissect = _SUBTREES.get((fd.message, fd.name))
    return None if dissect is None else dissect(frame)


def info(frame: Frame) -> str | None:
    """What the Info column says of a container message instead of its first fields (FTP: the packet
    itself, "OpenFileRO @PARAM/param.pck"), or None."""
    if frame.msgdef is not None and frame.msgdef.name == ftp.MESSAGE:
        p = ftp.ftp(frame)
        return None if p is None else ftp.summary(p)
    return None


__all__ = ["SPECS", "Node", "Spec", "info", "subtree"]
