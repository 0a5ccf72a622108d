"""What the kernel says it dropped: /proc/net/udp{,6} per socket inode (Linux), packet-socket statistics.

Both are the kernel's own counter of datagrams that arrived while the socket's receive buffer was full
(`sk_drops`); the receiver also reads the same counter per datagram through SO_RXQ_OVFL ancillary data,
and /proc catches drops that happened after the last datagram was received.
"""

from __future__ import annotations

import os
import socket
import struct

SOL_PACKET = getattr(socket, "SOL_PACKET", 263)
PACKET_STATISTICS = 6
_TPACKET_STATS = struct.Struct("II")  # tp_packets, tp_drops


def socket_inode(sock: socket.socket) -> int:
    """The inode number /proc/net/* lists for `sock`."""
    return os.fstat(sock.fileno()).st_ino


def proc_udp_drops(inode: int, proc: str = "/proc/net") -> int | None:
    """The `drops` column of the UDP socket with `inode` in /proc/net/udp or udp6; None when unavailable."""
    want = str(inode)
    for name in ("udp", "udp6"):
        try:
            with open(os.path.join(proc, name), encoding="ascii") as f:
                lines = f.readlines()
        except OSError:
            continue
        header = lines[0].split() if lines else []
        for line in lines[1:]:
            cols = line.split()
            if len(cols) > 9 and cols[9] == want:
                try:
                    return int(cols[-1]) if header and header[-1] == "drops" else None
                except ValueError:
                    return None
    return None


def packet_socket_drops(sock: socket.socket) -> tuple[int, int] | None:
    """(packets, drops) of an AF_PACKET socket since the last call (the kernel resets them on read)."""
    try:
        raw = sock.getsockopt(SOL_PACKET, PACKET_STATISTICS, _TPACKET_STATS.size)
    except OSError:
        return None
    packets, drops = _TPACKET_STATS.unpack(raw)
    return packets, drops
