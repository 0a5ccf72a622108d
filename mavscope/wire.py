"""MAVLink's wire constants and the size of a frame from its first bytes: the one place that knows them.

Below every layer that looks at MAVLink bytes: the tlog reader (capture) tells where an entry's frame
ends, the framer (mavlink) where a frame ends, from the same three bytes (STX, LEN, INCOMPAT).
"""

from __future__ import annotations

STX_V1 = 0xFE
STX_V2 = 0xFD
HEADER_V1 = 6  # STX LEN SEQ SYS COMP MSGID
HEADER_V2 = 10  # STX LEN INCOMPAT COMPAT SEQ SYS COMP MSGID(3)
CRC_LEN = 2
SIGNATURE_LEN = 13  # link id (1), timestamp (6), signature (6)
IFLAG_SIGNED = 0x01


def frame_size(buf: bytes, pos: int) -> int:
    """Total size of the frame whose STX is at `pos` (from STX, LEN and, for v2, INCOMPAT: the caller
    makes sure the three bytes are there); -1 when buf[pos] is not an STX."""
    stx = buf[pos]
    if stx == STX_V2:
        return HEADER_V2 + buf[pos + 1] + CRC_LEN + (SIGNATURE_LEN if buf[pos + 2] & IFLAG_SIGNED else 0)
    if stx == STX_V1:
        return HEADER_V1 + buf[pos + 1] + CRC_LEN
    return -1
