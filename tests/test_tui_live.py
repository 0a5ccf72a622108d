"""Follow mode: `mavscope tui --live --udp PORT` shows frames as they arrive, within bounded memory."""

from __future__ import annotations

import socket

from mavscope.capture.detect import open_capture
from mavscope.commands.tui import parse_options
from mavscope.transport.decap import Decapsulator
from mavscope.tui.app import create_app
from tests.tui_helpers import CAPTURES, SIZE, run, wait_for


def _payloads(n: int) -> list[bytes]:
    out = []
    decap = Decapsulator()
    with open_capture(CAPTURES / "px4_sitl_udp.pcap") as reader:
        for rec in reader:
            out.extend(p.data for p in decap.feed(rec) if p.transport == "udp" and p.data[:1] == b"\xfd")
            if len(out) >= n:
                break
    return out[:n]


def test_live_follow_mode_shows_frames_as_they_arrive_and_drops_the_oldest() -> None:
    async def scenario() -> None:
        app = create_app(None, parse_options(["--live", "--udp", "127.0.0.1:0", "--keep", "1000"]))
        async with app.run_test(size=SIZE) as pilot:
            await wait_for(pilot, lambda: app.source.udp is not None and app.source.udp.sock is not None)
            port = app.source.udp.bound.port
            tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            datagrams = _payloads(1200)
            for d in datagrams[:10]:
                tx.sendto(d, ("127.0.0.1", port))
            await wait_for(pilot, lambda: app.packet_list.count >= 10)
            assert app.index.row(0).msgname == "HEARTBEAT"
            assert "live" in str(app.status.render())
            await pilot.press("end")  # on the last line: the list follows new frames
            for d in datagrams[10:]:
                tx.sendto(d, ("127.0.0.1", port))
            await wait_for(pilot, lambda: app.index.first > 0 and app.index.first + len(app.index) >= 1300)
            await pilot.pause(0.3)
            assert len(app.index) <= 1000  # bounded
            assert app.packet_list.cursor == app.packet_list.count - 1  # still following
            assert app.tree.detail is not None
            tx.close()
            await pilot.press("k")
            assert app.add_key("key", "passphrase:x").startswith("live capture")
        assert app.source.udp.stopping

    run(scenario())
