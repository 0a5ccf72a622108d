"""Whether the audit's command matcher could give up a command, for the export's native source, without
feeding it every command.

The matcher (analysis/command_log.CommandMatcher) holds one waiting command a key (message, command id,
sender, target: a retry of a waiting command is the same key) and gives up a command only when more than
PENDING_MAX keys wait at once, its only part of `audit`'s findings (a capacity finding). So while a capture
has sent no more distinct keys than that, the matcher gives up nothing and needs no frame; the native feed
counts the keys from the payload rows (`CommandKeys.window`), and where they pass the bound the export runs
the matcher over a pure pass (export/pure.command_pass) instead. Building a Frame and decoding every command
would cost the native path about a tenth of its time on a telemetry mix with 4% commands.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from mavscope.analysis.command_log import PENDING_MAX, command_fields
from mavscope.mavlink.dialect import MessageDef
from mavscope.mavlink.frame import Frame
from mavscope.native.chunk import Chunk

SENT = ("COMMAND_LONG", "COMMAND_INT")  # the messages that send a command (the matcher's waiting ones)


def payload_rows(parts: Sequence[tuple[int, Any, Any, int]], position: int, length: int,
                 ) -> tuple[np.ndarray, np.ndarray] | None:
    """The window's rows of the message at `position` of the table (`length` bytes each): the index of
    each in the chunk and their payloads (count x length), or None when the window has none."""
    part = next((p for p in parts if p[0] == position), None)
    if part is None:
        return None
    _, rows, frames, count = part
    at = np.frombuffer(frames, np.uint32, count=count).astype(np.int64)
    return at, np.frombuffer(rows, np.uint8, count=count * length).reshape(count, length)


def command_layout(md: MessageDef) -> tuple[int, int, int] | None:
    """A command message's command, target_system and target_component offsets where its fields are
    common.xml's (uint16_t, uint8_t, uint8_t); None for another message or another layout."""
    if md.name not in SENT:
        return None
    want = {"command": "uint16_t", "target_system": "uint8_t", "target_component": "uint8_t"}
    got = [md.field(n) for n in want]
    offsets = [fd.offset for fd, kind in zip(got, want.values())
               if fd is not None and fd.type == kind and not fd.array_length]
    return (offsets[0], offsets[1], offsets[2]) if len(offsets) == 3 else None


def command_key(name: str, command: int, sysid: int, compid: int, tsys: int, tcomp: int) -> object:
    """The matcher's key (message, command, sender, target), packed as `CommandKeys.window` packs a row's
    where its parts fit."""
    if 0 <= command < 1 << 16 and 0 <= tsys < 256 and 0 <= tcomp < 256:
        return SENT.index(name) << 48 | command << 32 | sysid << 24 | compid << 16 | tsys << 8 | tcomp
    return (name, command, sysid, compid, tsys, tcomp)


class CommandKeys:
    """The distinct command keys a capture sent, window by window (`window`), until `may_give_up`."""

    def __init__(self, messages: Sequence[MessageDef]) -> None:
        self.messages = messages
        self.sent = np.array([md.name in SENT for md in messages], np.bool_)  # per message of the table
        # COMMAND_LONG / COMMAND_INT where their layout is common.xml's: (position, length, command, target
        # system and target component offsets)
        self.layouts = [(k, md.length, *at) for k, md in enumerate(messages) if (at := command_layout(md)) is not None]
        self.keys: set[object] = set()

    @property
    def may_give_up(self) -> bool:
        """Whether the matcher could have given up a command: more distinct keys sent than it holds."""
        return len(self.keys) > PENDING_MAX

    def window(self, c: Chunk, py: Sequence[Frame], parts: Sequence[tuple[int, Any, Any, int]]) -> None:
        """The keys the window's frames send, as the matcher makes them: the native rows' from their payload
        rows (where the layout is common.xml's; under any other each row counts as a key of its own, an upper
        bound), the handed-back frames' (`py`) from their decoded fields."""
        keys = self.keys
        for position, length, cmd_at, ts_at, tc_at in self.layouts:
            got = payload_rows(parts, position, length)
            if got is None:
                continue
            at, payload = got
            name = SENT.index(self.messages[position].name)
            cmd = payload[:, cmd_at].astype(np.int64) | payload[:, cmd_at + 1].astype(np.int64) << 8
            packed = (name << 48 | cmd << 32 | c.sysid[at].astype(np.int64) << 24 | c.compid[at].astype(np.int64) << 16
                      | payload[:, ts_at].astype(np.int64) << 8 | payload[:, tc_at])
            keys.update(np.unique(packed).tolist())
        odd = self.sent[c.message]
        if self.layouts:
            odd &= ~np.isin(c.message, [p for p, *_ in self.layouts])
        if odd.any():
            keys.update(("row", r, i) for r, i in zip(c.record[odd].tolist(), c.index[odd].tolist()))
        for f in py:
            fields = command_fields(f) if f.msgname in SENT else None
            if fields is not None:
                try:
                    keys.add(command_key(str(f.msgname), int(fields["command"]),  # type: ignore[call-overload]
                                         f.sysid, f.compid, int(fields["target_system"]),  # type: ignore[call-overload]
                                         int(fields["target_component"])))  # type: ignore[call-overload]
                except (KeyError, TypeError, ValueError):  # the matcher skips it
                    pass
