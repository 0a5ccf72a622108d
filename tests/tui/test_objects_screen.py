"""The objects screen (`o`), driven with Textual's Pilot on the Lua upload capture: what it lists is the
generator's truth (captures/ftp_lua_upload.truth.json), the pane shows the script's own text, Enter
jumps to the object's first frame, and a display filter narrows the list to the objects it touches."""

from __future__ import annotations

import json

from textual.widgets import DataTable, Static

from mavscope.tui.app import create_app
from mavscope.tui.screens.objects import ObjectsScreen
from scripts.capgen.objects import LUA_SCRIPT
from tests.support.tui import CAPTURES, SIZE, open_analysis, ready, run, type_text, wait_for

LUA = CAPTURES / "ftp_lua_upload.pcap"
TRUTH = json.loads((CAPTURES / "ftp_lua_upload.truth.json").read_text())


def test_objects_screen_lists_previews_and_jumps() -> None:
    async def scenario() -> None:
        app = create_app(LUA)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("o")
            assert isinstance(app.screen, ObjectsScreen)
            await wait_for(pilot, lambda: app.screen.result is not None)
            screen = app.screen
            log = screen.result
            assert [(o.kind, o.path) for o in log.objects] == [(o["kind"], o["path"]) for o in TRUTH["objects"]]
            table = screen.query_one("#objects", DataTable)
            assert table.row_count == len(TRUTH["objects"])
            await pilot.press("down")  # the upload of the Lua script
            await pilot.pause()
            text = str(screen.query_one("#object-preview", Static).render())
            assert LUA_SCRIPT.decode().splitlines()[0] in text
            detail = str(screen.query_one("#object-detail", Static).render())
            assert TRUTH["objects"][1]["sha256"] in detail and "255/230 → 1/1" in detail
            notes = str(screen.query_one("#object-notes", Static).render())
            assert "RemoveFile /APM/scripts/../LOGS/00000042.BIN" in notes and "script-upload" in notes
            first = log.objects[1].first_frame
            await pilot.press("enter")
            await pilot.pause()
            assert app.screen is app.screen_stack[0]
            assert app.index.row(app.packet_list.cursor_row).record == first

    run(scenario())


def test_objects_screen_under_a_filter_and_with_nothing_to_show() -> None:
    async def scenario() -> None:
        app = create_app(LUA)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("slash")
            await type_text(pilot, "ftp.opcode == CreateFile")
            await pilot.press("enter")
            await wait_for(pilot, lambda: app.packet_list.count == 2)
            await open_analysis(pilot, "escape", "o")
            assert [o.kind for o in app.screen.result.objects] == ["ftp-write", "ftp-write"]  # the two uploads
            await pilot.press("escape")
        app = create_app(CAPTURES / "px4_sitl_udp.pcap")
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await open_analysis(pilot, "o")
            assert app.screen.result.objects == []
            assert "No file" in str(app.screen.query_one("#objects-title").render())

    run(scenario())
