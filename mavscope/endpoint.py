"""Endpoint: an IP address and a port, the one value every layer uses for where a frame came from.

The transport layer makes them (interned per address, so a capture holds a handful), live capture
parses the user's `--udp` and `--forward` into them, packet synthesis writes them back into headers,
filters read `address` and `port`, and output prints `text` ("127.0.0.1:14550", "[::1]:14550"). Nothing
parses an "ip:port" string back.
"""

from __future__ import annotations

import ipaddress
import socket
from dataclasses import dataclass, field

IPAddress = ipaddress.IPv4Address | ipaddress.IPv6Address


@dataclass(frozen=True, slots=True)
class Endpoint:
    """An IP endpoint. `host` is the numeric address; `family` is socket.AF_INET or socket.AF_INET6."""

    host: str
    port: int
    family: int = socket.AF_INET
    address: IPAddress = field(init=False, repr=False, compare=False)
    text: str = field(init=False, repr=False, compare=False)  # "ip:port", "[v6]:port"

    def __post_init__(self) -> None:
        # frozen: computed once here, read on every frame that prints or filters the endpoint
        object.__setattr__(self, "address", ipaddress.ip_address(self.host))
        v6 = self.family == socket.AF_INET6
        object.__setattr__(self, "text", f"[{self.host}]:{self.port}" if v6 else f"{self.host}:{self.port}")

    def __str__(self) -> str:
        return self.text

    @classmethod
    def from_packed(cls, packed: bytes, port: int) -> Endpoint:
        """From a 4- or 16-byte address as it is in an IP header."""
        if len(packed) == 4:
            return cls(socket.inet_ntop(socket.AF_INET, packed), port, socket.AF_INET)
        return cls(socket.inet_ntop(socket.AF_INET6, packed), port, socket.AF_INET6)

    @property
    def packed(self) -> bytes:
        return self.address.packed
