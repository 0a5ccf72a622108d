"""Sequence loss of one sender, computed apart from mavscope: ported from the derivation of the real
captures' facts that was written against pymavlink without reading mavscope's sequence code (its
`_walk()`). Only the robust rule is kept.

An unwrapped counter `top` and a set of missing positions; for each frame, delta = (seq - top) mod 256:
0 is the same number again; 1..127 moves forward (the skipped positions become missing); 128..255 is
behind by 256 - delta: it fills a missing position (a late frame) or fills nothing. RESET_RUN frames
behind in a row, each continuing the previous one, are a restarted counter: re-based above `top`, not
counted as behind.

MAVLink keeps one counter per channel (the C library's `mavlink_status_t` per channel), so a sender heard
on several channels is walked per channel and the walks summed (`walk_channels`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import NamedTuple

RESET_RUN = 10


class Walk(NamedTuple):
    frames: int
    missing: int  # positions still missing at the end
    late: int  # frames that filled a missing position
    same: int  # frames with the number of the highest position so far
    behind: int  # frames behind the counter that filled nothing (resets excluded)
    resets: int


def walk(seqs: Sequence[int]) -> Walk:
    missing: set[int] = set()
    same = late = behind = resets = 0
    top: int | None = None
    run: list[int] = []  # indices of consecutive behind-not-filling frames
    for i, s in enumerate(seqs):
        if top is None:
            top = s
            continue
        delta = (s - top) % 256
        if delta == 0:
            same += 1
            run = []
        elif delta < 128:
            missing.update(range(top + 1, top + delta))
            top += delta
            run = []
        else:
            p = top - (256 - delta)
            if p in missing:
                missing.discard(p)
                late += 1
                run = []
            else:
                behind += 1
                run = run + [i] if run and (s - seqs[run[-1]]) % 256 == 1 else [i]
                if len(run) >= RESET_RUN:
                    top = (top // 256 + 2) * 256 + seqs[run[0]] + len(run) - 1
                    behind -= len(run)
                    resets += 1
                    run = []
    return Walk(len(seqs), len(missing), late, same, behind, resets)


def walk_channels(channels: Iterable[Sequence[int]]) -> Walk:
    """One sender's walks, one per channel, summed."""
    walks = [walk(seqs) for seqs in channels]
    return Walk(*(sum(w[i] for w in walks) for i in range(len(Walk._fields))))


def walk_merged(frames: Sequence[tuple[tuple[int, int], int]]) -> dict[tuple[int, int], int]:
    """Ids numbering their frames on one counter (one program sending as several, on one channel), walked
    as that one counter: `frames` are the group's (sender, seq) in capture order. Each position still
    missing at the end is charged to the sender of the frame that revealed it (the first frame past it),
    so each frame lost from the shared counter counts once. Returns sender -> positions charged (every
    sender of `frames` present)."""
    charged: dict[int, tuple[int, int]] = {}  # missing position -> the sender that revealed it
    top: int | None = None
    for sender, s in frames:
        if top is None:
            top = s
            continue
        delta = (s - top) % 256
        if 0 < delta < 128:
            charged.update((p, sender) for p in range(top + 1, top + delta))
            top += delta
        elif delta >= 128:
            charged.pop(top - (256 - delta), None)  # a late frame fills its position
    out = {sender: 0 for sender, _ in frames}
    for sender in charged.values():
        out[sender] += 1
    return out
