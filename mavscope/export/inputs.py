"""Which files of FILES_OR_DIRS are captures.

A file named on the command line is a capture, whatever it holds (as `read` takes it). A file found
by walking a directory is one when its content says so: a pcap, pcapng or tlog; or a raw byte stream
whose first 64 KiB hold a MAVLink frame with a valid CRC (so that READMEs, notes and other files
that happen to sit beside the captures are passed over, and counted); so is what is no regular file.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field

from mavscope.capture.detect import SNIFF, detect_kind
from mavscope.capture.reader import open_file, pread
from mavscope.errors import CaptureError
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus
from mavscope.mavlink.framing import Framer

MAX_FILES = 1_000_000  # files looked at under the directories given, at most


@dataclass
class Inputs:
    captures: list[str] = field(default_factory=list)
    # entries of the directories that are not captures: other files, and what is no regular file (a FIFO,
    # which a read would wait on for ever, a socket, a device, a dangling or a directory's symbolic link)
    passed_over: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)  # paths given that do not exist
    stopped: bool = False  # MAX_FILES entries looked at: the walk stopped there


def _holds_mavlink(path: str, framer: Framer) -> bool:
    try:
        spath, f, size = open_file(path)
    except CaptureError:
        return False
    try:
        head = pread(f, min(size, SNIFF), 0)
    except OSError:
        return False
    finally:
        f.close()
    found, _, _ = framer.scan(head, 0, len(head), True)
    return any(status is CrcStatus.OK for _, _, status, _ in found)


def is_capture(path: str, framer: Framer) -> bool:
    """Whether a file found in a directory is a capture (see the module's docstring)."""
    try:
        kind = detect_kind(path)
    except CaptureError:
        return False
    return kind != "raw" or _holds_mavlink(path, framer)


def find_captures(paths: Iterable[str], dialect: Dialect) -> Inputs:
    """The captures named by `paths` (files, and directories walked in name order, hidden entries and
    `_`-prefixed ones skipped: an export dataset's own files never count as input)."""
    framer = Framer(dialect.messages)
    out = Inputs()
    seen = 0
    for p in paths:
        if os.path.isdir(p):
            for folder, dirs, files in os.walk(p):
                dirs[:] = sorted(d for d in dirs if not d.startswith((".", "_")))
                links = [d for d in dirs if os.path.islink(os.path.join(folder, d))]  # os.walk does not follow
                for name in sorted(files + links):
                    if name.startswith((".", "_")):
                        continue
                    seen += 1
                    if seen > MAX_FILES:
                        out.stopped = True
                        return out
                    full = os.path.join(folder, name)
                    regular = os.path.isfile(full)  # (through a link to one too)
                    (out.captures if regular and is_capture(full, framer) else out.passed_over).append(full)
        elif os.path.exists(p):
            out.captures.append(p)
        else:
            out.missing.append(p)
    return out
