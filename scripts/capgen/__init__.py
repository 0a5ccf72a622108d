"""mavscope's sample-capture generator: byte for byte the same captures on every run and machine.

Run it through `scripts/make_captures.py` (or `make captures`); `build.make_all` writes everything.

The generator imports nothing from mavscope: the tests compare mavscope against these captures, so
they must be built by implementations independent of mavscope's. MAVLink frames are encoded (and
signed) by pymavlink; encrypted frames and the key exchange by `encode` and `kex` here, written from
their specification (docs/security.md, dissectors/mavscope.xml) with hashlib and `cryptography`.
Ethernet/IP/UDP/TCP headers, with correct checksums, are built by scapy. The capture files themselves
(pcap, pcapng, tlog, raw) are written with `struct`: scapy's writers take time from float seconds
(rounding) or from the wall clock when a packet has none, and its pcapng writer cannot give two
interfaces different time resolutions.

Determinism: a fixed base time, one seeded `random.Random` per capture, integer microsecond (or
nanosecond) timestamps, explicit MAC/IP addresses, IP ids, TCP sequence numbers and signing
timestamps; floats are computed with + - * / only (no libm calls whose last bit may differ between
platforms). Nothing reads the clock or the environment.

Besides the captures the generator writes `expected.json` (what a correct decoder must report, computed
from what was generated, not by decoding) and `README.md` (the same in prose).

This `__init__` imports nothing, so that `encode` can be imported alone (by tests that build frames
with it) without scapy or the rest of the generator.
"""
