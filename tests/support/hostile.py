"""One capture (and one dialect) whose every string is hostile, for the tests that walk every command and
every TUI screen (tests/cli/test_hostile_words.py, tests/tui/test_hostile_screens.py).

Built with pymavlink (FTP packets by pymavlink's own `mavftp_op.FTP_OP`, through tests/support/ftpflows):
STATUSTEXT text, PARAM_VALUE and PARAM_SET param_id, NAMED_VALUE_FLOAT/INT name, FTP paths of OpenFileRO,
ListDirectory, CreateFile and RemoveFile, the names of a directory listing's entries, a file's bytes, and a
COMMAND_LONG of a command the hostile dialect defines, whose parameter labels and units are hostile too.
Each string holds an OSC 0 (set the window title), an OSC 52 (set the clipboard), a CSI (SGR) sequence,
C1 controls (U+009B, the 8-bit CSI; U+0085), bidi overrides and isolates, a zero-width space, CR/LF, rich
markup (`[blink red]`) and the literal four characters `\\x1b` (which must not print as the ESC does).
"""

from __future__ import annotations

import re
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as v2

from tests.support.flows import command_long, heartbeat
from tests.support.ftpflows import CREATE, GCS, LIST, REMOVE, VEHICLE, WRITE, Flow, read_file

OSC0 = "\x1b]0;pwned\x07"
OSC52 = "\x1b]52;c;ZWNobyBwd25lZA==\x07"  # base64 of "echo pwned"
CSI = "\x1b[31m"
C1 = "\x9b"  # the 8-bit CSI, as the character U+009B (UTF-8 c2 9b)
NEL = "\x85"
RLO, LRI = "\u202e", "\u2066"
ZWSP = "\u200b"
MARKUP = "[blink red]"
LITERAL = "\\x1b"  # the four characters backslash, x, 1, b

# The strings the capture carries (each within its field's size in bytes).
STATUS = f"{OSC0}{CSI}{C1}{RLO}\r\n{MARKUP}{LITERAL}"  # STATUSTEXT.text, char[50]
STATUS2 = f"{OSC52}{LRI}{ZWSP}{NEL}x"  # a second one
PARAM_IDS = (f"{MARKUP}\x1b[2J", f"{OSC52[:5]}\x07\r\n{RLO}")  # PARAM_VALUE.param_id, char[16]
NAMED = (f"\x1b]0;N\x07\r\n{C1}", f"[blink]{RLO}")  # NAMED_VALUE_FLOAT/INT.name, char[10]
FILE_PATH = f"/{OSC0}/{OSC52}/{C1}{RLO}\r\n{MARKUP}/{LITERAL}.txt"
DIR_PATH = f"/{CSI}{MARKUP}{LRI}"
ENTRY = f"e{OSC0}{MARKUP}"  # a file name in the directory listing
UPLOAD_PATH = f"/APM/scripts/{MARKUP}{C1}.lua"
FILE_DATA = f"line\r{CSI}{OSC0}text\n".encode()

# What a terminal must never get: C0 controls but tab and newline, DEL, C1 controls, bidi overrides and
# isolates, zero-width and other format characters, lone surrogates (Unicode: Cc, Cf, Cs).
RAW = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u200b-\u200f\u2028-\u202e\u2060-\u206f\ufeff\ud800-\udfff]")

# The hostile dialect: a command (MAV_CMD 31990) with hostile parameter labels and units, an enum entry
# with a hostile description. XML 1.0 cannot carry C0 controls (not even as character references, but
# tab, CR, LF), so these carry C1, bidi, CR/LF and markup.
HOSTILE_LABEL = "Gain\u009b[blink red]\u202e\r\nforged"
HOSTILE_UNITS = "m\u2066[bold]"
DIALECT_XML = """<?xml version="1.0"?>
<mavlink>
  <version>3</version>
  <dialect>0</dialect>
  <enums>
    <enum name="MAV_CMD">
      <entry value="31990" name="MAV_CMD_HOSTILE_TEST">
        <description>desc&#x9b;[blink red]&#13;&#10;x</description>
        <param index="1" label="Gain&#x9b;[blink red]&#x202e;&#13;&#10;forged" units="m&#x2066;[bold]">first</param>
      </entry>
    </enum>
  </enums>
</mavlink>
"""
HOSTILE_COMMAND = 31990


def write_dialect(tmp: Path) -> Path:
    path = tmp / "hostile.xml"
    path.write_text(DIALECT_XML, encoding="utf-8")
    return path


def _b(s: str, size: int) -> bytes:
    data = s.encode()
    assert len(data) <= size, (s, len(data), size)
    return data


def hostile_flow() -> Flow:
    flow = Flow()
    flow.send(VEHICLE, heartbeat())
    flow.send(GCS, heartbeat(gcs=True))
    flow.send(VEHICLE, v2.MAVLink_statustext_message(6, _b(STATUS, 50), 0, 0))
    flow.send(VEHICLE, v2.MAVLink_statustext_message(4, _b(STATUS2, 50), 0, 0))
    for i, pid in enumerate(PARAM_IDS):
        flow.send(GCS, v2.MAVLink_param_set_message(1, 1, _b(pid, 16), 2.5, 9))
        flow.send(VEHICLE, v2.MAVLink_param_value_message(_b(pid, 16), 2.5, 9, 2, i))
    flow.send(VEHICLE, v2.MAVLink_named_value_float_message(1000, _b(NAMED[0], 10), 1.5))
    flow.send(VEHICLE, v2.MAVLink_named_value_int_message(1000, _b(NAMED[1], 10), 7))
    flow.send(GCS, command_long(HOSTILE_COMMAND, 2.0))
    flow.send(VEHICLE, v2.MAVLink_command_ack_message(HOSTILE_COMMAND, 0))
    flow.send(VEHICLE, v2.MAVLink_global_position_int_message(1000, 473_977_420, 85_455_940, 500_000, 10_000,
                                                               0, 0, 0, 0))
    read_file(flow, FILE_PATH, FILE_DATA)
    req = flow.request(LIST, data=DIR_PATH.encode())
    flow.reply(req, data=f"F{ENTRY}\t5\0D{MARKUP}\0".encode())
    req = flow.request(CREATE, data=UPLOAD_PATH.encode(), session=1)
    flow.reply(req, session=1)
    req = flow.request(WRITE, session=1, data=b"print('\x1b]0;x\x07')\n")
    flow.reply(req, session=1)
    req = flow.request(REMOVE, data=f"/{OSC52}".encode())
    flow.nak(req, 10)
    flow.send(VEHICLE, heartbeat())
    return flow


def write_capture(tmp: Path, name: str = "hostile.tlog") -> Path:
    return hostile_flow().write(tmp, name)
