"""A tlog of signed frames with every signature verdict, built with pymavlink (tests/support/security.py):
what each frame's verdict is comes from the construction and MAVLink's signing rules (the MAVLink 2
signing spec: a frame's MAC is SHA-256 over key, header, payload, CRC, link id and timestamp; a stream's
timestamp must grow, so a frame repeated byte for byte is a replay; a frame signed with another key has a
MAC no given key makes)."""

from __future__ import annotations

from pathlib import Path

from tests.support.flows import T0, tlog
from tests.support.security import PASSPHRASE, SHA_KEY, command_long, heartbeat, signer

KEY_OPTION = ("--key", f"passphrase:{PASSPHRASE}")  # SHA-256 of the passphrase: SHA_KEY
# frame number -> the verdict the frame gets with KEY_OPTION
VERDICTS = {1: "valid", 2: "valid", 3: "replay", 4: "invalid", 5: "valid", 6: "truncated"}


def write_signed(tmp: Path, name: str = "verdicts.tlog") -> Path:
    good = signer(SHA_KEY)
    f1 = heartbeat(good)  # the stream's first frame, its MAC the key's
    f2 = command_long(good)  # the next timestamp
    f3 = f2  # the same frame again: its timestamp is not newer (replay)
    other = signer(b"\x01" * 32, timestamp=good.signing.timestamp + 10)
    f4 = command_long(other)  # a newer timestamp, a MAC of another key (invalid)
    f5 = heartbeat(good)
    f6 = heartbeat(good)[:-3]  # cut in its signature, the file's last record (truncated)
    path = tmp / name
    path.write_bytes(tlog([(T0 + i, f) for i, f in enumerate([f1, f2, f3, f4, f5, f6])]))
    return path
