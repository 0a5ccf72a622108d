"""MAVLink's own C parser (pymavlink's mavlink_helpers.h, the code in ArduPilot, PX4 and QGroundControl),
compiled here, as the independent side of the tests on what a vehicle reads from bytes.

The C library reads byte by byte (`mavlink_parse_char` in PX4 and QGroundControl, `mavlink_frame_char_buffer`
in ArduPilot, which end a damaged frame differently): it drops a v2 frame at its INCOMPAT_FLAGS byte
when a flag it does not know is set, and looks for the next STX from the byte after. The length-based
readers (pymavlink's Python parser, Wireshark) skip the whole frame instead, so the two can disagree on
what a datagram holds. This module runs the real thing: a small program built from pymavlink's C headers
(generator/C/include_v2.0) and a message table (CRC_EXTRA and lengths) written from pymavlink's own parse
of the XML dialects (mavparse), with no mavscope code. Each datagram is parsed from a reset parser, as a
receiver that takes one datagram at a time would start, or all of them one after another with one parser,
as the receivers on a UDP port read them; what comes out is where each frame that passed
(MAVLINK_FRAMING_OK) starts and its size.

`c_parser()` builds the program once per test session (None when no C compiler is found: tests skip).
"""

from __future__ import annotations

import functools
import os
import shutil
import struct
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

import pymavlink
from pymavlink.generator import mavparse

ROOT = Path(__file__).resolve().parents[2]
HEADERS = Path(pymavlink.__file__).parent / "generator" / "C" / "include_v2.0"

_MAIN = r"""
#include <stdio.h>
#include <stdint.h>
#include <string.h>

#define MAVLINK_STX 253
#define MAVLINK_ENDIAN MAVLINK_LITTLE_ENDIAN
#define MAVLINK_ALIGNED_FIELDS 1
#define MAVLINK_CRC_EXTRA 1
#define MAVLINK_COMMAND_24BIT 1
#define MAVLINK_COMM_NUM_BUFFERS 1
#include "mavlink_types.h"
#define MAVLINK_MESSAGE_CRCS {%s}
#include "protocol.h"

/* argv[1] "parse": mavlink_parse_char; "frame": mavlink_frame_char_buffer. argv[2] "keep": the parser
 * goes on from one datagram to the next (a UDP port's receiver), else it starts each afresh.
 * stdin: datagrams as (uint32 little-endian length, bytes); stdout: "datagram start size" per frame read,
 * start below 0 for a frame that began in an earlier datagram */
int main(int argc, char **argv) {
    const int frame = argc > 1 && strcmp(argv[1], "frame") == 0;
    const int keep = argc > 2 && strcmp(argv[2], "keep") == 0;
    static uint8_t buf[1 << 20];
    uint8_t lenb[4];
    unsigned long n = 0;
    while (fread(lenb, 1, 4, stdin) == 4) {
        uint32_t len = (uint32_t)lenb[0] | ((uint32_t)lenb[1] << 8) | ((uint32_t)lenb[2] << 16)
                     | ((uint32_t)lenb[3] << 24);
        if (len > sizeof buf || fread(buf, 1, len, stdin) != len)
            return 2;
        if (!keep || n == 0) {
            memset(mavlink_get_channel_status(0), 0, sizeof(mavlink_status_t));
            memset(mavlink_get_channel_buffer(0), 0, sizeof(mavlink_message_t));
        }
        for (uint32_t i = 0; i < len; i++) {
            mavlink_message_t msg;
            mavlink_status_t status;
            mavlink_message_t *rx = mavlink_get_channel_buffer(0);
            mavlink_status_t *st = mavlink_get_channel_status(0);
            const uint8_t r = frame ? mavlink_frame_char_buffer(rx, st, buf[i], &msg, &status)
                                    : mavlink_parse_char(0, buf[i], &msg, &status);
            if (r == MAVLINK_FRAMING_OK) {
                unsigned size = msg.magic == MAVLINK_STX_MAVLINK1 ? 8u + msg.len
                              : 12u + msg.len + ((msg.incompat_flags & MAVLINK_IFLAG_SIGNED) ? 13u : 0u);
                printf("%%lu %%ld %%u\n", n, (long)i + 1 - (long)size, size);
            }
        }
        n++;
    }
    return 0;
}
"""


def _dialect_files() -> list[Path]:
    """The XML mavscope loads by default: pymavlink's all.xml (with what it includes), then dissectors/."""
    base = Path(pymavlink.__file__).parent / "dialects" / "v20" / "all.xml"
    return [base, *sorted((ROOT / "dissectors").glob("*.xml"))]


def message_table() -> str:
    """MAVLINK_MESSAGE_CRCS entries {msgid, crc_extra, min_len, max_len, 0, 0, 0} from mavparse, by msgid."""
    entries: dict[int, tuple[int, int, int]] = {}
    for path in _dialect_files():
        xmls = [mavparse.MAVXML(str(path), mavparse.PROTOCOL_2_0)]
        seen = {str(path)}
        i = 0
        while i < len(xmls):  # the includes, each once
            for inc in xmls[i].include:
                p = os.path.join(os.path.dirname(xmls[i].filename), inc)
                if p not in seen:
                    seen.add(p)
                    xmls.append(mavparse.MAVXML(p, mavparse.PROTOCOL_2_0))
            i += 1
        for x in xmls:
            for m in x.message:
                entries.setdefault(m.id, (m.crc_extra, m.wire_min_length, m.wire_length))
    return ", ".join(f"{{{i}, {c}, {lo}, {hi}, 0, 0, 0}}" for i, (c, lo, hi) in sorted(entries.items()))


class CParser:
    def __init__(self, exe: Path) -> None:
        self.exe = exe

    def frames(self, datagrams: Sequence[bytes], entry: str | None = None, keep: bool = False
               ) -> list[set[tuple[int, int]]]:
        """For each datagram, the (start, size) of every frame the C library reads that ends in it: through
        `entry` ("parse": mavlink_parse_char, PX4 and QGroundControl; "frame": mavlink_frame_char_buffer,
        ArduPilot), or through either (None). With `keep` one parser reads the datagrams one after another,
        as a UDP port's receiver does (a start below 0: the frame began in an earlier datagram); else
        each datagram is parsed from a reset parser."""
        data = b"".join(struct.pack("<I", len(d)) + d for d in datagrams)
        found: list[set[tuple[int, int]]] = [set() for _ in datagrams]
        for e in ("parse", "frame") if entry is None else (entry,):
            out = subprocess.run([str(self.exe), e, "keep" if keep else "reset"], input=data, capture_output=True,
                                 check=True).stdout
            for line in out.decode().splitlines():
                n, start, size = (int(x) for x in line.split())
                found[n].add((start, size))
        return found

    def frames_of(self, datagram: bytes, entry: str | None = None) -> set[tuple[int, int]]:
        return self.frames([datagram], entry)[0]


@functools.lru_cache(maxsize=1)
def c_parser() -> CParser | None:
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None or not (HEADERS / "mavlink_helpers.h").exists():
        return None
    work = Path(tempfile.mkdtemp(prefix="mavscope-cparser-"))
    src = work / "parse.c"
    src.write_text(_MAIN % message_table())
    exe = work / "parse"
    subprocess.run([cc, "-O1", "-w", "-I", str(HEADERS), "-o", str(exe), str(src)], check=True,
                   capture_output=True)
    return CParser(exe)



def require_c_parser() -> CParser:
    """The built parser, or the test skips (no C compiler)."""
    import pytest

    p = c_parser()
    if p is None:
        pytest.skip("no C compiler to build MAVLink's C parser with")
    return p
