"""Pilot tests of `mavscope tui`: every flow of the issue, driven by keys and clicks."""

from __future__ import annotations

from array import array
from pathlib import Path

import pytest

from mavscope.commands.tui import parse_options
from mavscope.errors import CaptureError, UsageError
from mavscope.mavlink.frame import CrcStatus, SignatureStatus
from mavscope.tui.app import MavscopeApp, create_app
from mavscope.tui.messages import FilterProgress
from mavscope.tui.screens.expert import ExpertScreen
from mavscope.tui.screens.help import HelpScreen
from mavscope.tui.screens.keys import KeyDialog
from mavscope.tui.screens.mission import MissionScreen
from mavscope.tui.screens.stats import StatsScreen
from mavscope.tui.widgets.hex_view import ASCII_START, byte_column
from tests.conftest import Cli
from tests.support.builders import heartbeat_msg, tlog_us, write_pcap
from tests.support.tui import CAPTURES, SIZE, open_analysis, ready, run, type_text, wait_for

PX4 = CAPTURES / "px4_sitl_udp.pcap"


def _first_row(app: MavscopeApp, msgname: str, **fields: object) -> int:
    for i in range(len(app.index)):
        if app.index.row(i).msgname == msgname:
            d = app.index.detail(i)
            if all(d.fields and d.fields.get(k) == v for k, v in fields.items()):
                return i
    raise AssertionError(f"no {msgname} {fields}")


def test_factory_used_by_the_cli_reports_a_missing_file_before_drawing(tmp_path) -> None:
    with pytest.raises(CaptureError):
        create_app(tmp_path / "missing.pcap")
    with pytest.raises(UsageError):
        create_app(PX4, parse_options([str(PX4), "--key", "nonsense"]))


def test_navigation_keys_move_the_cursor_and_the_tree_follows() -> None:
    async def scenario() -> None:
        app = create_app(PX4)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            pl = app.packet_list
            assert app.focused is pl and pl.cursor == 0
            assert app.tree.detail.frame.record == 1
            await pilot.press("down", "down")
            assert pl.cursor == 2
            await pilot.press("up")
            assert pl.cursor == 1
            await pilot.press("pagedown")
            assert pl.cursor == 1 + pl.page
            await pilot.press("pageup")
            assert pl.cursor == 1
            await pilot.press("end")
            await pilot.pause()
            assert pl.cursor == len(app.index) - 1
            assert pl.visible_rows()[-1] == len(app.index) - 1  # scrolled to the end
            assert app.tree.detail.frame == app.index.frame(len(app.index) - 1)
            await pilot.press("home")
            await pilot.pause()
            assert pl.cursor == 0 and pl.visible_rows()[0] == 0
            # mouse: a click on the 4th frame's line (after the pane's top border and the header line)
            await pilot.click(pl, offset=(10, 5))
            assert pl.cursor == 3
            assert app.hex.data == app.index.frame(3).raw

    run(scenario())


def test_enter_opens_the_tree_with_header_and_payload_expanded_and_tab_cycles_panes() -> None:
    async def scenario() -> None:
        app = create_app(PX4)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("enter")
            assert app.focused is app.tree
            top = {n.data.name: n for n in app.tree.root.children}
            assert top["mavlink.header"].is_expanded and top["mavlink.payload"].is_expanded
            assert app.tree.cursor_node.data.name == "mavlink.payload"
            await pilot.press("tab")
            assert app.focused is app.hex
            await pilot.press("tab")
            assert app.focused is app.packet_list
            await pilot.press("tab")
            assert app.focused is app.tree
            await pilot.press("shift+tab", "shift+tab")
            assert app.focused is app.hex

    run(scenario())


def test_mission_item_int_shows_the_waypoint_parameter_labels() -> None:
    async def scenario() -> None:
        app = create_app(PX4)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            row = _first_row(app, "MISSION_ITEM_INT", command=16)
            app.packet_list.move_to(row)
            await pilot.pause()
            payload = next(n for n in app.tree.root.children if n.data.name == "mavlink.payload")
            labels = [str(n.label) for n in payload.children]
            for want in ("Hold (param1)", "Accept Radius (param2)", "Pass Radius (param3)", "Yaw (param4)",
                         "Latitude (x): 47.", "Longitude (y): 8.", "Altitude (z)"):
                assert any(lab.startswith(want) for lab in labels), (want, labels)
            assert any("°" in lab for lab in labels if lab.startswith("Latitude"))
            assert any(str(n.label).startswith("CRC: ") and "[ok]" in str(n.label) for n in app.tree.root.children)

    run(scenario())


def test_hex_highlight_follows_the_tree_and_a_byte_click_selects_its_field() -> None:
    async def scenario() -> None:
        app = create_app(PX4)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("enter")
            await pilot.pause()
            cur = app.tree.cursor_node.data
            assert app.hex.highlight == (cur.offset, cur.length)
            await pilot.press("down")  # the first payload field
            await pilot.pause()
            cur = app.tree.cursor_node.data
            assert cur.name == "HEARTBEAT.custom_mode"
            assert app.hex.highlight == (cur.offset, cur.length) == (10, 4)
            # click byte 5 (the system id) in the hex column, then byte 0x11 (in the ASCII column)
            await pilot.click(app.hex, offset=(byte_column(5) + 1 + 1, 0))  # +1: the pane's left padding
            await pilot.pause()
            assert app.tree.cursor_node.data.name == "mavlink.sysid"
            assert app.hex.highlight == (5, 1)
            await pilot.click(app.hex, offset=(ASCII_START + 1 + 1, 1))  # byte 17: the CRC
            await pilot.pause()
            assert app.tree.cursor_node.data.name in ("HEARTBEAT.system_status", "HEARTBEAT.mavlink_version",
                                                      "mavlink.crc")
            it = app.tree.cursor_node.data
            assert it.offset <= 17 < it.offset + it.length
            # arrow keys in the hex pane walk the bytes and the tree follows
            await pilot.press("left")
            await pilot.pause()
            it = app.tree.cursor_node.data
            assert it.offset <= 16 < it.offset + it.length

    run(scenario())


def test_filter_bar_apply_inline_error_at_the_position_and_escape() -> None:
    async def scenario() -> None:
        app = create_app(PX4)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("slash")
            assert app.focused is app.filter_bar.input
            await type_text(pilot, "COMMAND_LONG")
            await pilot.press("enter")
            await wait_for(pilot, lambda: app.status.filtering is None and app.status.shown == 2)
            assert app.focused is app.packet_list
            assert [app.index.row(r).msgname for r in app.packet_list.visible_rows()] == ["COMMAND_LONG"] * 2
            assert app.tree.detail.frame.msgname == "COMMAND_LONG"
            # an error: shown under the bar, caret under the offending text, cursor put there
            await pilot.press("slash")
            await type_text(pilot, " and mavlink.sysid == banana")
            await pilot.press("enter")
            await pilot.pause()
            text = app.filter_bar.text
            err = app.filter_bar.error
            assert err, "no error shown"
            caret = err.index("^") - len("Filter: ")
            assert text[caret:].startswith("banana")
            assert app.filter_bar.input.cursor_position == caret
            assert app.focused is app.filter_bar.input
            assert app.packet_list.count == 2  # the previous filter still applies
            await pilot.press("escape")
            assert app.focused is app.packet_list
            # clearing the filter shows every frame again, the cursor stays on its frame
            row = app.packet_list.cursor_row
            await pilot.press("slash")
            app.filter_bar.input.value = ""
            await pilot.press("enter")
            await pilot.pause()
            assert app.packet_list.count == len(app.index)
            assert app.packet_list.cursor_row == row
            assert not app.filter_bar.error

    run(scenario())


def test_filter_given_on_the_command_line_applies_at_start() -> None:
    async def scenario() -> None:
        app = create_app(PX4, parse_options([str(PX4), "-Y", "MISSION_ITEM_INT"]))
        async with app.run_test(size=SIZE) as pilot:
            await wait_for(pilot, lambda: app.index.done and app.status.shown == 4 and app.status.filtering is None)
            assert app.filter_bar.text == "MISSION_ITEM_INT"
            assert len(app.index) == 1371  # the index holds every frame: the filter can be changed

    run(scenario())


@pytest.mark.parametrize("key, screen", [("s", StatsScreen), ("m", MissionScreen), ("e", ExpertScreen)])
def test_analysis_screens_open_show_results_and_close(key: str, screen: type) -> None:
    async def scenario() -> None:
        app = create_app(PX4)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press(key)
            assert isinstance(app.screen, screen)
            await wait_for(pilot, lambda: app.screen.result is not None)
            if key == "s":
                links = {lk["sysid"]: lk for lk in app.screen.result.links_json()}
                assert links[1]["received"] == 1303 and links[1]["lost"] == 0
                assert app.screen.query_one("#rates").row_count == 17
            elif key == "m":
                t = app.screen.result.transfers
                assert len(t) == 1 and t[0].complete and len(t[0].items) == 4
                assert app.screen.query_one("#items").row_count == 4
                assert len(app.screen.result.track) > 100
            else:
                assert app.screen.result == []
            await pilot.press("escape")
            assert app.screen is app.screen_stack[0]

    run(scenario())


def test_expert_findings_enter_jumps_to_the_frame() -> None:
    async def scenario() -> None:
        app = create_app(CAPTURES / "commands_ack.pcap")
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await open_analysis(pilot, "e")
            findings = app.screen.result
            assert any(f.code == "key-leak" for f in findings)
            await pilot.press("enter")  # the first (most severe) finding
            await pilot.pause()
            assert app.screen is app.screen_stack[0]
            assert app.packet_list.cursor_row is not None
            assert app.index.row(app.packet_list.cursor_row).record == findings[0].frames[0]

    run(scenario())


def test_key_dialog_adds_a_passphrase_and_the_verdicts_update() -> None:
    async def scenario() -> None:
        app = create_app(CAPTURES / "signed_udp.pcap")
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            assert app.index.row(0).signature_status is SignatureStatus.NO_KEY
            await pilot.press("down", "down")
            await pilot.press("k")
            assert isinstance(app.screen, KeyDialog)
            await type_text(pilot, "wrong:x")
            await pilot.press("down")  # not an arrow for the input: harmless
            app.screen.query_one("#key-input").value = ""
            await pilot.click("#key-add")
            assert "enter a key" in str(app.screen.query_one("#key-error").render())
            await pilot.click("#key-input")
            await type_text(pilot, "mavscope-demo")
            await pilot.press("enter")
            await wait_for(pilot, lambda: app.pending is None and app.screen is app.screen_stack[0])
            assert all(app.index.row(i).signature_status is SignatureStatus.VALID for i in range(len(app.index)))
            assert app.packet_list.cursor == 2  # the cursor stayed where it was
            sig = next(n for n in app.tree.root.children if n.data.name == "signature")
            status = next(n for n in sig.children if n.data.name == "signature.status")
            assert str(status.label).startswith("Status: valid (key key1)")
            assert "1 signing key" in app.status.keys

    run(scenario())


def test_key_dialog_tab_from_the_key_lands_on_add() -> None:
    """Issue 11 #10: Tab from the typed key went to Cancel, and Enter there lost the key without a word."""
    async def scenario() -> None:
        app = create_app(CAPTURES / "signed_udp.pcap")
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("k")
            await type_text(pilot, "mavscope-demo")
            await pilot.press("tab")
            assert app.focused is not None and app.focused.id == "key-add"
            await pilot.press("enter")
            await wait_for(pilot, lambda: app.pending is None and app.screen is app.screen_stack[0])
            assert all(app.index.row(i).signature_status is SignatureStatus.VALID for i in range(len(app.index)))

    run(scenario())


def test_key_dialog_shows_the_command_lines_error_for_a_bad_key() -> None:
    async def scenario() -> None:
        app = create_app(CAPTURES / "signed_udp.pcap")
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("k")
            await pilot.click("#kind-2", offset=(6, 0))  # hex
            await pilot.click("#key-input")
            await type_text(pilot, "abcd")
            await pilot.press("enter")
            await pilot.pause()
            assert isinstance(app.screen, KeyDialog)
            assert "32 bytes" in str(app.screen.query_one("#key-error").render())
            await pilot.press("escape")
            assert app.screen is app.screen_stack[0] and app.pending is None

    run(scenario())


def test_help_lists_every_binding_and_q_quits() -> None:
    async def scenario() -> None:
        app = create_app(PX4)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("question_mark")
            assert isinstance(app.screen, HelpScreen)
            await pilot.press("escape")
            assert app.screen is app.screen_stack[0]
            await pilot.press("q")
            await pilot.pause()
        assert app.return_code == 0

    run(scenario())


def test_ctrl_c_quits_from_the_list_and_from_a_screen() -> None:
    """Issue: Ctrl-C asked to press Ctrl-Q; it quits, as termshark does (the help lists it)."""
    from mavscope.tui.bindings import KEYS

    assert ("Ctrl+C", "quit", "everywhere") in KEYS
    for opener in (None, "s"):
        async def scenario() -> None:
            app = create_app(PX4)
            async with app.run_test(size=SIZE) as pilot:
                await ready(pilot)
                if opener:
                    await pilot.press(opener)
                await pilot.press("ctrl+c")
                await pilot.pause()
            assert app.return_code == 0 and not app.is_running

        run(scenario())


def test_damaged_capture_rows_carry_their_verdicts() -> None:
    async def scenario() -> None:
        app = create_app(CAPTURES / "damaged.pcap")
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            statuses = [app.index.row(i).crc_status for i in range(len(app.index))]
            assert statuses.count(CrcStatus.BAD) == 2 and CrcStatus.UNCHECKED in statuses
            bad = statuses.index(CrcStatus.BAD)
            app.packet_list.move_to(bad)
            await pilot.pause()
            crc = next(n for n in app.tree.root.children if n.data.name == "mavlink.crc")
            assert "[bad, should be 0x" in str(crc.label)
            assert "ff5f5f" in str(crc.label.style) or any("ff5f5f" in str(s.style) for s in crc.label.spans)

    run(scenario())


def test_a_superseded_filter_runs_late_message_does_not_replace_the_view() -> None:
    """The same filter started again (after a key, or rows judged again) while its first run still had
    a message in flight: that message belongs to the cancelled run and is ignored."""
    async def scenario() -> None:
        app = create_app(CAPTURES / "px4_sitl_udp.pcap")
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            app.apply_filter("HEARTBEAT")
            await wait_for(pilot, lambda: app.status.filtering is None and app.packet_list.view is not None)
            shown = app.packet_list.count
            assert shown > 0
            flt = app.display_filter
            app._start_filter(flt, keep_row=None)
            app.post_message(FilterProgress(flt, array("I"), 0, 1, False))  # the first run, late
            await wait_for(pilot, lambda: app.status.filtering is None)
            assert app.packet_list.count == shown

    run(scenario())


@pytest.mark.parametrize("engine", ["pure", "native"])
def test_a_payload_filter_selects_the_frames_pymavlink_decodes_so(engine: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The filter worker over the index's columns (mavscope.browse.fastfilter), on the pure and the native
    index: `GLOBAL_POSITION_INT.relative_alt > 1000 || (HEARTBEAT && mavlink.sysid == 255)` shows exactly
    the frames pymavlink's own decoder (tests/support/pymavlink_reader.py, no mavscope code) says match, in
    capture order."""
    from tests.support.pymavlink_reader import read_pcap

    monkeypatch.setenv("MAVSCOPE_PURE", "1" if engine == "pure" else "")
    msgs = read_pcap(PX4)
    expected = [k for k, m in enumerate(msgs) if (m.name == "GLOBAL_POSITION_INT" and m.msg.relative_alt > 1000)
                or (m.name == "HEARTBEAT" and m.src[0] == 255)]
    assert len(expected) > 10
    text = "GLOBAL_POSITION_INT.relative_alt > 1000 || (HEARTBEAT && mavlink.sysid == 255)"

    async def scenario() -> None:
        app = create_app(PX4, parse_options([str(PX4), "-Y", text]))
        async with app.run_test(size=SIZE) as pilot:
            await wait_for(pilot, lambda: app.index.done and app.status.filtering is None
                           and app.status.shown == len(expected))
            assert len(app.index) == len(msgs)  # the same frames, so positions compare
            assert list(app._filter_rows) == expected
            assert [app.index.row(n).record for n in expected] == [msgs[k].index for k in expected]

    run(scenario())


def test_problems_reading_the_capture_are_said_once_it_is_indexed(cli: Cli, tmp_path: Path) -> None:
    """A damaged capture does not pass in silence in the TUI either, nor an empty list unexplained: once
    indexed, a notification gives the count of problems and the first as `read` writes it on stderr, and
    the status line keeps the count (stop 20: nothing said; a capture of no frame showed an empty list)."""
    empty = tmp_path / "other-link.pcap"  # one record of a link type mavscope does not decode (DLT 147: USER0)
    write_pcap(empty, [(1.0, b"\xfd\x00\x00\x00")], linktype=147, snaplen=65535)

    async def scenario(path: Path, head: str | None) -> None:
        _, _, err = cli("read", path)
        lines = [ln.split(": ", 2)[2] for ln in err.splitlines() if ln.startswith(f"mavscope: {path}: ")]
        app = create_app(path)
        async with app.run_test(size=SIZE) as pilot:
            await wait_for(pilot, lambda: app.indexed_at is not None)
            said = [n.message for n in app._notifications]
            if head is None:
                assert lines == [] and said == [] and app.status.problems == 0
            else:
                assert said == [f"{head}; the first: {lines[0]}"] and app.status.problems == len(lines)

    run(scenario(CAPTURES / "damaged.pcap", "1 problem(s) reading the capture"))
    run(scenario(empty, "no MAVLink frames found in this capture"))
    run(scenario(PX4, None))


def test_the_events_screen_shows_a_statustexts_escape_sequences_escaped(tmp_path: Path) -> None:
    """A STATUSTEXT carrying an SGR colour, an OSC 8 hyperlink and BEL (made with pymavlink) shows them as
    Python's repr writes them, never as bytes for the terminal; a closing tag of rich markup stays text."""
    from pymavlink.dialects.v20 import ardupilotmega as apm
    from textual.widgets import DataTable

    mav = apm.MAVLink(None, srcSystem=1, srcComponent=1)
    words = b"\x1b[31mRED\x1b]8;;http://e.example\x07x [/bold]"
    path = tmp_path / "words.tlog"
    path.write_bytes(tlog_us((1_700_000_000_000_000 + i, m.pack(mav)) for i, m in enumerate(
        [heartbeat_msg(2, 3), apm.MAVLink_statustext_message(6, words, 0, 0)])))

    async def scenario() -> None:
        app = create_app(path)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await open_analysis(pilot, "v")
            table = app.screen.query_one(DataTable)
            cells = [str(getattr(c, "plain", c)) for r in range(table.row_count) for c in table.get_row_at(r)]
            shown = [c for c in cells if "RED" in c]
            assert shown and "\\x1b[31mRED\\x1b]8;;http://e.example\\x07x [/bold]" in shown[0]
            assert not any("\x1b" in c or "\x07" in c for c in cells)

    run(scenario())


def test_analysis_tables_list_the_first_rows_and_say_how_many_there_are(monkeypatch: pytest.MonkeyPatch) -> None:
    """With the limit at 3 rows, the statistics screen's message rates of px4_sitl_udp.pcap (17 streams)
    list 3 and the title says 3 of 17 and where the rest is; the mission screen's items (4) list 3. Textual
    laid out 200,000 mission transfers for 30 s when every one was a row."""
    monkeypatch.setattr("mavscope.tui.screens.analysis.TABLE_ROWS", 3)

    async def scenario() -> None:
        app = create_app(PX4)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await open_analysis(pilot, "s")
            messages = app.screen.result.messages_json()
            assert len(messages) == 17 and app.screen.query_one("#rates").row_count == 3
            title = str(app.screen.query_one("#rates-title").content)
            assert title.endswith("(the first 3 of 17 listed: `mavscope stats --json` has them all)")
            await pilot.press("escape")
            await open_analysis(pilot, "m")
            [t] = app.screen.result.transfers
            assert len(t.items) == 4 and app.screen.query_one("#items").row_count == 3
            assert "(the first 3 of 4 listed" in str(app.screen.query_one("#items-title").content)

    run(scenario())


def test_a_file_name_with_escapes_is_shown_escaped(tmp_path: Path) -> None:
    """The title and the status bar name the capture; a file name may hold ESC and rich's markup."""
    name = "x\x1b]0;owned\x07[bold]y.pcap"
    path = tmp_path / name
    path.write_bytes((CAPTURES / "damaged.pcap").read_bytes())  # damage: a notice of problems

    async def scenario() -> None:
        app = create_app(path)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            assert app.title == "mavscope: " + str(tmp_path / "x\\x1b]0;owned\\x07[bold]y.pcap")
            status = app.status.render()
            assert "\\x1b]0;owned\\x07[bold]y.pcap" in str(status) and "\x1b" not in str(status)

    run(scenario())

