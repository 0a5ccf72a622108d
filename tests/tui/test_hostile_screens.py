"""Every TUI screen on a hostile capture (tests/support/hostile.py) with a hostile dialect: no control,
format or bidi character of the capture or the dialect reaches the terminal, and none of their words is
read as markup (issue 35 items 5 and 6(d): the Objects screen wrote FTP paths raw, so an OSC 0 set the
terminal's title and an OSC 52 its clipboard; `[blink red]` in a dialect's name blinked on the statistics
screen).

Driven with Textual's Pilot: the main screen with every frame under the cursor (packet list, detail tree,
hex), then every screen the app's key bindings open (taken from MavscopeApp.BINDINGS, so a new screen is
walked too), each row of its tables highlighted in turn. What is checked is what the screen would draw:
the segments of the compositor's strips. Expected: no character of hostile.RAW in any segment, no segment
blinking (mavscope never blinks: any blink is the capture's `[blink red]` or `[blink]` read as markup), and
the escaped forms, written here by hand from the strings hostile.py builds, on the screens that show them.
"""

from __future__ import annotations

from pathlib import Path

from textual.widgets import DataTable

from mavscope.pipeline.options import PipelineOptions
from mavscope.tui.app import MavscopeApp, create_app
from mavscope.tui.screens.analysis import AnalysisScreen
from mavscope.tui.sessions import TuiOptions
from tests.support import hostile
from tests.support.tui import ready, run, wait_for

SIZE = (240, 60)  # wide enough that the escaped words are not cut short
# The escaped forms, by hand: ESC as \x1b, BEL \x07, U+009B \x9b, U+202E \u202e, CR/LF \r\n, the literal
# backslash of hostile.LITERAL doubled.
FILE_PATH = r"/\x1b]0;pwned\x07/\x1b]52;c;ZWNobyBwd25lZA==\x07/\x9b\u202e\r\n[blink red]/\\x1b.txt"
STATUS = r"\x1b]0;pwned\x07\x1b[31m\x9b\u202e\r\n[blink red]\\x1b"
PARAM = r"[blink red]\x1b[2J"
LABEL = r"Gain\x9b[blink red]\u202e\r\nforged"


def _screen_text(app: MavscopeApp) -> str:
    """What the screen draws, after checking each segment."""
    lines = []
    for strip in app.screen._compositor.render_strips():
        line = []
        for seg in strip:
            bad = hostile.RAW.search(seg.text)
            assert bad is None, (type(app.screen).__name__, seg.text)
            assert not (seg.style is not None and seg.style.blink), (type(app.screen).__name__, seg.text)
            line.append(seg.text)
        lines.append("".join(line))
    return "\n".join(lines)


async def _walk_tables(pilot, seen: list[str]) -> None:  # type: ignore[no-untyped-def]
    """Every row of every table of the screen under the cursor, the screen checked at each."""
    app = pilot.app
    seen.append(_screen_text(app))
    for table in app.screen.query(DataTable):
        table.focus()
        for _ in range(table.row_count):
            await pilot.press("down")
            await pilot.pause()
            seen.append(_screen_text(app))


def test_every_screen_shows_hostile_words_escaped(tmp_path: Path) -> None:
    cap = hostile.write_capture(tmp_path)
    dialect = hostile.write_dialect(tmp_path)
    options = TuiOptions(pipeline=PipelineOptions(dialects=(str(dialect),)))
    screens = [b for b in MavscopeApp.BINDINGS if b.action in
               ("stats", "mission", "objects", "expert", "events", "plot", "keys", "help")]
    assert {b.action for b in screens} == {"stats", "mission", "objects", "expert", "events", "plot", "keys",
                                           "help"}, "a binding of MavscopeApp is not walked here"

    async def scenario() -> None:
        app = create_app(cap, options)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            main: list[str] = []
            for _ in range(len(app.index)):  # every frame: its line, tree and bytes
                main.append(_screen_text(app))
                await pilot.press("down")
                await pilot.pause()
            text = "\n".join(main)
            assert f"text='{STATUS}'" in text  # the packet list's Info (repr: the value in quotes)
            assert FILE_PATH in text  # the FTP summary and the tree's ftp.path
            # the hostile command's parameter label, on the COMMAND_LONG's tree
            app.packet_list.move_to(next(i for i in range(len(app.index)) if app.index.row(i).msgid == 76))
            await pilot.pause()
            await wait_for(pilot, lambda: LABEL in _screen_text(app))
            # a number field under the tree's cursor, for `p`
            app.tree.focus()
            await pilot.press("down")
            await pilot.pause()
            walked: dict[str, str] = {}
            for b in screens:
                seen: list[str] = []
                await pilot.press(b.key)
                await pilot.pause()
                if isinstance(app.screen, AnalysisScreen):
                    await wait_for(pilot, lambda: app.screen.result is not None)
                    await pilot.pause()
                await _walk_tables(pilot, seen)
                walked[b.action] = "\n".join(seen)
                await pilot.press("escape")
                await pilot.pause()
            assert FILE_PATH in walked["objects"] and "[blink red]" in walked["objects"]
            assert STATUS in walked["events"] and PARAM in walked["events"]

    run(scenario())


def test_the_word_widgets_never_read_markup() -> None:
    """Defence in depth for names a dialect may still bring (issue 35 item 6(d): `[blink red]` in a message
    name blinked on the statistics screen): the screens' Table, Title and Pane show a `str` escaped and as
    written, whatever it holds."""
    from textual.app import App, ComposeResult

    from mavscope.tui.widgets.words import Pane, Table, Title

    word = "[blink red]MSG\x1b]0;t\x07\u202e"
    shown = r"[blink red]MSG\x1b]0;t\x07\u202e"  # by hand

    class Words(App[None]):
        def compose(self) -> ComposeResult:
            yield Title(word)
            yield Pane(word)
            yield Table()

        def on_mount(self) -> None:
            table = self.query_one(Table)
            table.add_columns(word, "n")
            table.add_row(word, "1")

    async def scenario() -> None:
        app = Words()
        async with app.run_test(size=(80, 10)) as pilot:
            await pilot.pause()
            text = _screen_text(app)  # type: ignore[arg-type]
            assert text.count(shown) == 4, text

    run(scenario())
