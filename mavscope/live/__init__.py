"""Live capture: sources that turn datagrams or packets into Records as they arrive, and a pcap sink.

No terminal UI here: `mavscope live` (mavscope/commands/live.py) and a TUI's follow mode both drive a
`LiveSource` (open, start, iterate `records()`, stop, close) and feed its Records to the same pipeline
as offline captures (`pipeline.session.build_pipeline`). See docs/live.md.
"""

from mavscope.live.sink import LivePcapWriter
from mavscope.live.source import LiveSource, LiveStats
from mavscope.live.udp import UdpSource, parse_endpoint

__all__ = ["LivePcapWriter", "LiveSource", "LiveStats", "UdpSource", "parse_endpoint"]
