"""How a live capture stops: promptly, and without hiding anything.

The first SIGINT or SIGTERM stops the receiver (it drains what the kernel already holds) and gives the
decoder STOP_DECODE_S more seconds for the datagrams queued behind it; what is still queued after that
is written to the pcap (every datagram received is in the file) but not decoded, and counted
(`undecoded`, in the summary line). A second signal stops decoding at once. So a loaded capture stops
within about two seconds instead of decoding a 200,000-datagram queue, and nothing received is lost
from the pcap or from the counts.
"""

from __future__ import annotations

import time
from collections.abc import Callable

STOP_DECODE_S = 1.0  # seconds of decoding left after the first signal


class Stopper:
    """The decoding deadline of a stopping capture (`clock` is injectable for tests)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic, grace: float = STOP_DECODE_S) -> None:
        self.clock = clock
        self.grace = grace
        self.deadline: float | None = None  # None: not stopping
        self.undecoded = 0  # datagrams received but not decoded because the capture was stopping

    def signal(self) -> bool:
        """A stop was asked for: True the first time (decode a little longer), False after (stop now)."""
        if self.deadline is None:
            self.deadline = self.clock() + self.grace
            return True
        self.deadline = self.clock()
        return False

    def decode(self) -> bool:
        """Whether the next queued datagram is still decoded (else: counted in `undecoded`)."""
        if self.deadline is not None and self.clock() >= self.deadline:
            self.undecoded += 1
            return False
        return True

    def decode_many(self, n: int) -> bool:
        """`decode()` for `n` datagrams received together (a batch): all decoded or all counted."""
        if self.deadline is not None and self.clock() >= self.deadline:
            self.undecoded += n
            return False
        return True
