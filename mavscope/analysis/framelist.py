"""How many frame numbers a finding of the analyses lists (the first MAX_FRAMES; all are counted)."""

from __future__ import annotations

from mavscope.notes import FrameNumbers

MAX_FRAMES = 50  # frame numbers listed per finding


def frame_numbers() -> FrameNumbers:
    """Frame numbers for a finding: the first MAX_FRAMES kept, all of them counted."""
    return FrameNumbers(MAX_FRAMES)
