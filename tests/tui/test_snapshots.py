"""Snapshot tests of `mavscope tui` (pytest-textual-snapshot; Textual is pinned because these depend on it).

Update after an intended change with `make snapshots`, and look at the SVGs in
tests/tui/__snapshots__/test_snapshots/ before committing them.
"""

from __future__ import annotations

from mavscope.mavlink.frame import CrcStatus
from mavscope.tui.app import create_app
from tests.support.tui import CAPTURES, SIZE, ready, wait_for


def _row_of(app, msgname: str, **fields: object) -> int:  # type: ignore[no-untyped-def]
    for i in range(len(app.index)):
        if app.index.row(i).msgname == msgname:
            d = app.index.detail(i)
            if all(d.fields and d.fields.get(k) == v for k, v in fields.items()):
                return i
    raise AssertionError(msgname)


def test_main_screen_mission_item_int_with_parameter_labels(snap_compare) -> None:  # type: ignore[no-untyped-def]
    async def run_before(pilot) -> None:  # type: ignore[no-untyped-def]
        app = pilot.app
        await ready(pilot)
        app.packet_list.move_to(_row_of(app, "MISSION_ITEM_INT", command=16, seq=2))
        await pilot.pause()
        await pilot.press("enter")  # the tree, on the payload
        await pilot.press(*["down"] * 7)  # down to Altitude (z): the tree scrolls, the hex highlights it
        await pilot.pause()

    assert snap_compare(create_app(CAPTURES / "px4_sitl_udp.pcap"), run_before=run_before, terminal_size=SIZE)


def test_damaged_capture_shows_red_verdicts(snap_compare) -> None:  # type: ignore[no-untyped-def]
    async def run_before(pilot) -> None:  # type: ignore[no-untyped-def]
        app = pilot.app
        await ready(pilot)
        bad = next(i for i in range(len(app.index)) if app.index.row(i).crc_status is CrcStatus.BAD)
        app.packet_list.move_to(bad)
        await wait_for(pilot, lambda: len(app._notifications) == 1)  # the cut record, said once indexed
        await pilot.pause()

    assert snap_compare(create_app(CAPTURES / "damaged.pcap"), run_before=run_before, terminal_size=SIZE)


def test_help_screen(snap_compare) -> None:  # type: ignore[no-untyped-def]
    async def run_before(pilot) -> None:  # type: ignore[no-untyped-def]
        await ready(pilot)
        await pilot.press("question_mark")
        await pilot.pause()

    assert snap_compare(create_app(CAPTURES / "px4_sitl_udp.pcap"), run_before=run_before, terminal_size=SIZE)


def test_statistics_screen(snap_compare) -> None:  # type: ignore[no-untyped-def]
    async def run_before(pilot) -> None:  # type: ignore[no-untyped-def]
        await ready(pilot)
        await pilot.press("s")
        await wait_for(pilot, lambda: pilot.app.screen.result is not None)
        await pilot.pause()

    assert snap_compare(create_app(CAPTURES / "px4_sitl_udp.pcap"), run_before=run_before, terminal_size=SIZE)


def test_signed_capture_after_adding_the_key(snap_compare) -> None:  # type: ignore[no-untyped-def]
    async def run_before(pilot) -> None:  # type: ignore[no-untyped-def]
        app = pilot.app
        await ready(pilot)
        assert app.add_key("key", "passphrase:mavscope-demo") is None
        await wait_for(pilot, lambda: app.pending is None)
        await pilot.pause()

    assert snap_compare(create_app(CAPTURES / "signed_udp.pcap"), run_before=run_before, terminal_size=SIZE)


def test_objects_screen(snap_compare) -> None:  # type: ignore[no-untyped-def]
    async def run_before(pilot) -> None:  # type: ignore[no-untyped-def]
        await ready(pilot)
        await pilot.press("o")
        await wait_for(pilot, lambda: pilot.app.screen.result is not None)
        await pilot.press("down")  # the Lua script written to the vehicle: its text in the pane
        await pilot.pause()

    assert snap_compare(create_app(CAPTURES / "ftp_lua_upload.pcap"), run_before=run_before, terminal_size=SIZE)
