"""Follow mode: `mavscope tui --live --udp PORT` shows frames as they arrive, within bounded memory."""

from __future__ import annotations

import socket
from array import array

from mavscope.capture.detect import open_capture
from mavscope.commands.tui import parse_options
from mavscope.mavlink.frame import SignatureStatus
from mavscope.transport.decap import Decapsulator
from mavscope.tui.app import create_app
from mavscope.tui.messages import FilterProgress, IndexProgress
from mavscope.tui.screens.keys import KeyDialog
from mavscope.tui.widgets.packet_list import PacketList
from tests.support.security import PASSPHRASE, SHA_KEY, command_long, heartbeat, signer
from tests.support.tui import CAPTURES, SIZE, run, type_text, wait_for


def _payloads(n: int) -> list[bytes]:
    out = []
    decap = Decapsulator()
    with open_capture(CAPTURES / "px4_sitl_udp.pcap") as reader:
        for rec in reader:
            out.extend(p.data for p in decap.feed(rec) if p.transport == "udp" and p.data[:1] == b"\xfd")
            if len(out) >= n:
                break
    return out[:n]


async def bound_port(pilot, app) -> int:  # type: ignore[no-untyped-def]
    """The UDP port the live app listens on, once its capture thread has bound it."""
    await wait_for(pilot, lambda: app.source.udp is not None and app.source.udp.sock is not None)
    return int(app.source.udp.bound.port)


def test_live_follow_mode_shows_frames_as_they_arrive_and_drops_the_oldest() -> None:
    async def scenario() -> None:
        app = create_app(None, parse_options(["--live", "--udp", "127.0.0.1:0", "--keep", "1000"]))
        async with app.run_test(size=SIZE) as pilot:
            port = await bound_port(pilot, app)
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
            pl = app.packet_list
            await wait_for(pilot, lambda: app.index.end >= 1300 and not pl.stale and pl.count == len(app.index)
                           and app.tree.detail is not None
                           and app.tree.detail.frame == app.index.frame(app.index.end - 1))
            assert app.index.first > 0 and len(app.index) <= 1000  # bounded
            assert pl.cursor == pl.count - 1  # still following: the newest frame is selected
            tx.close()
        assert app.source.udp.stopping

    run(scenario())


def test_rows_dropped_while_a_selection_is_in_flight_are_skipped_not_fatal() -> None:
    """The CI race: the list posts "row 60 selected", the bounded index drops rows 0-99 before the app
    handles it. The stale message is ignored, lines of dropped rows render blank until the list takes
    them out, and then the cursor and the detail tree agree on a frame that is still held."""
    async def scenario() -> None:
        app = create_app(CAPTURES / "px4_sitl_udp.pcap")
        async with app.run_test(size=SIZE) as pilot:
            await wait_for(pilot, lambda: app.index.done and app.tree.detail is not None)
            pl = app.packet_list
            pl.move_to(50)
            await pilot.pause()
            assert app.tree.detail.frame == app.index.frame(50)
            record_50 = app.index.row(50).record
            pl.post_message(PacketList.Highlighted(60))
            app.index.trim(100)  # before the message is handled: frames 0-99 are gone
            assert pl.stale and pl.cursor_row == 50
            app.refresh()
            await pilot.pause()  # handled (ignored) and painted: nothing raised
            assert app.tree.detail.frame.record == record_50  # unchanged, not another frame's
            app.post_message(IndexProgress(app.index, app.index.progress))
            await pilot.pause()
            assert not pl.stale and pl.count == len(app.index)
            assert pl.cursor == 0 and pl.cursor_row == 100 and pl.visible_rows()[0] == 100
            assert app.tree.detail.frame == app.index.frame(100)
            await pilot.press("down")
            assert app.tree.detail.frame == app.index.frame(101)

    run(scenario())


def test_follow_mode_survives_moving_and_filtering_while_rows_are_dropped() -> None:
    """Keys pressed and a filter applied while a small bounded index drops rows under a steady stream."""
    async def scenario() -> None:
        app = create_app(None, parse_options(["--live", "--udp", "127.0.0.1:0", "--keep", "120"]))
        async with app.run_test(size=SIZE) as pilot:
            port = await bound_port(pilot, app)
            tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            datagrams = _payloads(1000)
            keys = ["up", "pageup", "down", "end", "home", "pagedown"]
            for n, start in enumerate(range(0, 600, 50)):
                for d in datagrams[start : start + 50]:
                    tx.sendto(d, ("127.0.0.1", port))
                await pilot.press(keys[n % len(keys)])
                await pilot.pause(0.02)
            await pilot.press("slash", *"HEARTBEAT", "enter")
            for d in datagrams[600:]:
                tx.sendto(d, ("127.0.0.1", port))
            tx.close()
            pl = app.packet_list

            def settled() -> bool:  # the last frame is in and the list has caught up with the drops
                shown = pl.visible_rows()
                return (app.index.end >= 1000 and not pl.stale and bool(shown)
                        and all(app.index.first <= r < app.index.end for r in shown)
                        and app.tree.detail is not None and app.tree.detail.frame.record
                        == app.index.row(pl.cursor_row).record)

            await wait_for(pilot, settled, timeout=10)
            assert len(app.index) <= 120
            assert all(app.index.row(r).msgname == "HEARTBEAT" for r in pl.visible_rows())

    run(scenario())


def test_worker_messages_arriving_while_the_app_exits_are_ignored() -> None:
    """The index and filter workers post from their threads; one handled after the widgets are gone
    (quitting during a live capture) must not raise."""
    async def scenario() -> None:
        app = create_app(CAPTURES / "px4_sitl_udp.pcap", parse_options([str(CAPTURES / "px4_sitl_udp.pcap"),
                                                                         "-Y", "HEARTBEAT"]))
        async with app.run_test(size=SIZE) as pilot:
            await wait_for(pilot, lambda: app.index.done and app.status.filtering is None)
            flt = app.display_filter
        app.on_index_progress(IndexProgress(app.index, app.index.progress))
        app.on_filter_progress(FilterProgress(flt, array("I"), 0, 0, True))

    run(scenario())


def test_a_key_added_while_live_judges_the_kept_frames_again_and_those_that_follow() -> None:
    """`k` in follow mode: the capture thread takes the key between two frames, judges the frames the
    index holds again (verdicts update on screen) and checks the ones after with the state that built;
    the dialog refuses a bad key with the command line's message."""
    async def scenario() -> None:
        app = create_app(None, parse_options(["--live", "--udp", "127.0.0.1:0"]))
        async with app.run_test(size=SIZE) as pilot:
            port = await bound_port(pilot, app)
            mav = signer(SHA_KEY)
            first = heartbeat(mav)
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
                tx.sendto(first, ("127.0.0.1", port))
                for _ in range(2):
                    tx.sendto(heartbeat(mav), ("127.0.0.1", port))
                await wait_for(pilot, lambda: app.packet_list.count == 3 and app.tree.detail is not None)
                assert app.index.row(0).signature_status is SignatureStatus.NO_KEY
                app.apply_filter("signature.status == valid")
                await wait_for(pilot, lambda: app.packet_list.view is not None)
                assert app.packet_list.count == 0
                await pilot.press("k")
                assert isinstance(app.screen, KeyDialog)
                await pilot.click("#kind-2", offset=(6, 0))  # hex
                await pilot.click("#key-input")
                await type_text(pilot, "abcd")
                await pilot.press("enter")
                await pilot.pause()
                assert "32 bytes" in str(app.screen.query_one("#key-error").render())
                await pilot.click("#kind-0", offset=(6, 0))  # passphrase
                app.screen.query_one("#key-input").value = PASSPHRASE
                await pilot.press("enter")
                # no traffic now: the capture thread takes the key while idle
                await wait_for(pilot, lambda: app.screen is app.screen_stack[0] and not app.status.activity)
                assert "1 signing key" in app.status.keys
                assert [app.index.row(n).signature_status for n in app.index.rows()] == [SignatureStatus.VALID] * 3
                await wait_for(pilot, lambda: app.packet_list.count == 3)  # the filter ran again
                app.apply_filter("")
                await wait_for(pilot, lambda: app.packet_list.view is None and app.tree.detail is not None)
                sig = next(n for n in app.tree.root.children if n.data.name == "signature")
                status = next(n for n in sig.children if n.data.name == "signature.status")
                assert str(status.label).startswith("Status: valid (key key1)")  # the open frame's tree too
                for _ in range(2):
                    tx.sendto(command_long(mav), ("127.0.0.1", port))
                tx.sendto(first, ("127.0.0.1", port))  # an old frame again
                await wait_for(pilot, lambda: app.packet_list.count == 6)
            verdicts = [app.index.row(n).signature_status for n in app.index.rows()]
            assert verdicts == [SignatureStatus.VALID] * 5 + [SignatureStatus.REPLAY]
            assert app.index.frame(4).security.key == "key1"

    run(scenario())
