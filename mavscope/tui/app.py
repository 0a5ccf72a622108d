"""The Textual app: packet list, detail tree and hex pane over a `FrameIndex`, with a filter bar.

`create_app(path, options)` builds it; `mavscope tui` and the tests both call it. The index is filled
by a thread worker that walks the pipeline once (`tui.sessions`: the same stages as `mavscope read`)
and posts progress messages (`tui.messages`); rows show as soon as the first batch is in. Display
filters run in another thread worker over the index, incrementally while the index is still growing.
Adding a key re-runs the pipeline into a new index and swaps it in when complete (replay verdicts
depend on every earlier frame); in follow mode the running security stage takes the key instead.
"""

from __future__ import annotations

import importlib
import os
import time
from array import array
from collections.abc import Sequence
from dataclasses import replace

from textual import events, work
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.widgets import Footer
from textual.worker import Worker, WorkerState, get_current_worker

from mavscope.browse.index import FrameIndex
from mavscope.errors import MavscopeError
from mavscope.filter import DisplayFilter, FilterError, compile_filter
from mavscope.mavlink.dialect import load_dialect
from mavscope.tui.messages import FilterProgress, IndexProgress, Rejudged
from mavscope.tui.sessions import FrameSource, LiveFrameSource, TuiOptions
from mavscope.tui.widgets.detail_tree import DetailTree
from mavscope.tui.widgets.filter_bar import FilterBar
from mavscope.tui.widgets.hex_view import HexView
from mavscope.tui.widgets.packet_list import PacketList
from mavscope.tui.widgets.status_bar import StatusBar
from mavscope.tui.workers import fill_index, scan_filter
from mavscope.visible import visible

PANES = ("#packets", "#tree", "#hex")
MAIN_SCREEN_ACTIONS = frozenset({"cycle", "filter", "stats", "mission", "objects", "expert", "events", "plot", "keys",
                                 "help"})


class MavscopeApp(App[None]):
    """Browse the MAVLink frames of one capture."""

    TITLE = "mavscope"
    CSS = """
    Screen { layout: vertical; }
    #packets { height: 1fr; min-height: 6; border-top: solid $primary-darken-2; }
    #tree { height: 1fr; min-height: 5; border-top: solid $primary-darken-2; }
    #hex-pane { height: 7; border-top: solid $primary-darken-2; }
    #packets, #tree, #hex-pane { border-title-color: $text-muted; }
    #packets:focus-within, #tree:focus, #hex-pane:focus-within { border-top: solid $accent;
                                                                border-title-color: $text; }
    """
    BINDINGS = [
        Binding("slash", "filter", "Filter"),
        Binding("s", "stats", "Statistics"),
        Binding("m", "mission", "Mission"),
        Binding("o", "objects", "Objects"),
        Binding("e", "expert", "Expert"),
        Binding("v", "events", "Events"),
        Binding("p", "plot", "Plot"),
        Binding("k", "keys", "Keys"),
        Binding("question_mark", "help", "Help"),
        Binding("q", "quit", "Quit"),
        Binding("ctrl+c", "quit", "Quit", show=False, priority=True),  # as termshark and tshark do
        Binding("tab", "cycle(1)", "Next pane", show=False, priority=True),
        Binding("shift+tab", "cycle(-1)", "Previous pane", show=False, priority=True),
    ]

    def __init__(self, source: FrameSource, index: FrameIndex) -> None:
        super().__init__()
        self.source = source
        self.dialect = source.dialect
        self.index = index
        self.pending: FrameIndex | None = None  # an index being rebuilt with new keys
        self.display_filter: DisplayFilter | None = None
        self._filter_rows: array | None = None  # the rows the current filter run fills
        self._filter_view_set = False
        self._keep_row: int | None = None
        self.keys_added: list[str] = []
        self.first_rows_at: float | None = None  # seconds from mount to the first rows (measured)
        self.indexed_at: float | None = None  # seconds from mount to the complete index
        self._mounted_at = 0.0

    # --- layout -------------------------------------------------------------------------------

    def compose(self) -> ComposeResult:
        initial = self.source.options.display_filter or ""
        yield FilterBar(initial, id="filter")
        yield PacketList(self.index, id="packets")
        yield DetailTree(id="tree")
        with VerticalScroll(id="hex-pane"):
            yield HexView(id="hex")
        yield StatusBar(os.path.basename(self.source.path), id="status")
        yield Footer()

    @property
    def packet_list(self) -> PacketList:
        return self.query_one(PacketList)

    @property
    def tree(self) -> DetailTree:  # type: ignore[override]  # shadows DOMNode.tree (a debug view) on purpose
        return self.query_one(DetailTree)

    @property
    def hex(self) -> HexView:
        return self.query_one(HexView)

    @property
    def filter_bar(self) -> FilterBar:
        return self.query_one(FilterBar)

    @property
    def status(self) -> StatusBar:
        return self.query_one(StatusBar)

    def on_mount(self) -> None:
        self.title = f"mavscope: {visible(str(self.source.path))}"
        self._mounted_at = time.perf_counter()
        self.packet_list.border_title = "Frames (Enter: details)"
        self.tree.border_title = "Detail"
        self.query_one("#hex-pane").border_title = "Bytes (click a byte to select its field)"
        self.packet_list.focus()
        self.status.keys = self._keys_text()
        self.status.update_status()
        self.build_index(self.index, self.source)
        initial = self.filter_bar.text
        if initial:
            self.apply_filter(initial)

    def on_unmount(self) -> None:
        self.workers.cancel_all()
        if isinstance(self.source, LiveFrameSource):
            self.source.stop()

    def on_worker_state_changed(self, event: Worker.StateChanged) -> None:
        if event.state is WorkerState.ERROR:
            err = event.worker.error
            self.notify(visible(f"{event.worker.name}: {type(err).__name__}: {err}"), title="mavscope: error",
                        severity="error", timeout=30, markup=False)

    # --- indexing -----------------------------------------------------------------------------

    @work(thread=True, group="index", exit_on_error=False)
    def build_index(self, index: FrameIndex, source: FrameSource) -> None:
        worker = get_current_worker()
        fill_index(index, source, self.post_message, lambda: worker.is_cancelled)

    @work(thread=True, group="rebuild", exit_on_error=False)
    def rebuild_index(self, index: FrameIndex, source: FrameSource) -> None:
        worker = get_current_worker()
        fill_index(index, source, self.post_message, lambda: worker.is_cancelled)

    def _torn_down(self) -> bool:
        """The main screen's widgets are going (the app is exiting; they are removed one by one): late worker
        messages have nothing to update."""
        screen = self.default_screen
        return not screen.query(PacketList) or not screen.query(StatusBar)

    def on_index_progress(self, msg: IndexProgress) -> None:
        if self._torn_down():
            return
        if msg.index is self.pending:
            self.status.activity = f"re-checking with the new key {msg.progress.fraction:.0%}"
            if msg.progress.done:
                self._swap_index(msg.index)
            self.status.update_status()
            return
        if msg.index is not self.index:
            return
        if self.first_rows_at is None and len(self.index):
            self.first_rows_at = time.perf_counter() - self._mounted_at
        if msg.progress.done and self.indexed_at is None:
            self.indexed_at = time.perf_counter() - self._mounted_at
            self._report_messages()
            if (notice := self.status.set_problems(len(self.index), *self.index.problems())) is not None:
                self.notify(visible(notice, keep_newlines=True), title="mavscope", severity="warning", timeout=10,
                            markup=False)
        self.status.progress = msg.progress
        if self.source.live:
            self.status.live = True
            self.status.capture = self.source.path
            self.title = f"mavscope: {visible(str(self.source.path))}"
        if self.packet_list.stale:  # a bounded live index dropped its oldest rows
            self.packet_list.drop_lines()
        if self.display_filter is None:
            self.packet_list.sync(follow=self.source.live)
        self.status.update_status()

    def on_rejudged(self, msg: Rejudged) -> None:
        if self._torn_down() or msg.index is not self.index:
            return
        self.status.activity = ""
        self.status.update_status()
        self.packet_list.redraw()
        row = self.packet_list.cursor_row
        if self.display_filter is not None:  # it may test the verdicts that changed
            self._start_filter(self.display_filter, keep_row=row)
        else:
            self._show_frame(row)
        self.notify(f"{msg.count:,} frames checked again; the frames that follow are checked with it too",
                    title="key added", timeout=6)

    def _report_messages(self) -> None:
        text = self.source.messages()
        if text:
            self.notify(visible(text, keep_newlines=True), title="mavscope", severity="warning", timeout=10,
                        markup=False)

    def _swap_index(self, index: FrameIndex) -> None:
        self._report_messages()
        old = self.index
        self.index = index
        self.pending = None
        self.status.activity = ""
        self.status.progress = index.progress
        self.status.keys = self._keys_text()
        row = self.packet_list.cursor_row
        self.packet_list.set_index(index)
        if self.display_filter is not None:
            self._start_filter(self.display_filter, keep_row=row)
        else:
            self.packet_list.set_view(None, keep_row=row)
        old.close()

    # --- selection ----------------------------------------------------------------------------

    def on_packet_list_highlighted(self, msg: PacketList.Highlighted) -> None:
        if not self._torn_down():
            self._show_frame(msg.row)

    def _show_frame(self, row: int | None) -> None:
        """Row `row` in the detail tree and hex pane (None: empty them)."""
        if row is None:
            self.tree.show(None)
            self.hex.show(b"")
            return
        try:
            detail = self.index.detail(row)
        except IndexError:  # dropped by the bounded live index meanwhile: the list posts the next row
            return
        self.tree.show(detail)
        self.hex.show(detail.frame.raw)

    def on_packet_list_activated(self, msg: PacketList.Activated) -> None:
        self._focus(self.tree)

    def on_detail_tree_item_highlighted(self, msg: DetailTree.ItemHighlighted) -> None:
        hexview = self.screen_stack[0].query(HexView).first(HexView) if self.screen_stack else None
        if hexview is None:  # shutting down
            return
        item = msg.item
        if item is None:
            hexview.set_highlight(0, 0)
        else:
            hexview.set_highlight(item.offset, item.length)

    def on_hex_view_byte_selected(self, msg: HexView.ByteSelected) -> None:
        self.tree.select_byte(msg.byte)

    def action_cycle(self, step: int) -> None:
        """Tab: packet list -> detail tree -> hex -> packet list (from the filter bar: the list)."""
        focused = self.focused
        current = -1
        for i, sel in enumerate(PANES):
            widget = self.query_one(sel)
            if focused is widget:
                current = i
        nxt = 0 if current < 0 else (current + step) % len(PANES)
        self._focus(self.query_one(PANES[nxt]))

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        # pane cycling and the screen keys belong to the main screen; dialogs keep their keys
        if action in MAIN_SCREEN_ACTIONS and len(self.screen_stack) > 1:
            return False
        return True

    # --- filtering ----------------------------------------------------------------------------

    def _focus(self, widget) -> None:  # type: ignore[no-untyped-def]
        """Focus now, not after the queued keys (Widget.focus defers): `/` then fast typing goes to the bar."""
        self.screen_stack[0].set_focus(widget)

    async def on_key(self, event: events.Key) -> None:
        """Keys typed right after `/` in one burst (a paste without bracketed paste, a fast typist) were
        already queued for the widget focused before: hand them to the filter bar they were meant for."""
        bar = self.filter_bar.input if self.screen is self.screen_stack[0] else None
        if bar is None or self.focused is not bar:
            return
        if event.key == "enter":
            await bar.action_submit()
        elif event.key == "backspace":
            bar.action_delete_left()
        elif event.is_printable and event.character:
            bar.insert_text_at_cursor(event.character)
        else:
            return
        event.stop()
        event.prevent_default()

    def action_filter(self) -> None:
        bar = self.filter_bar
        if not bar.error:
            bar.input.cursor_position = len(bar.input.value)
        self._focus(bar.input)

    def on_filter_bar_left(self, msg: FilterBar.Left) -> None:
        self._focus(self.packet_list)

    def on_filter_bar_submitted(self, msg: FilterBar.Submitted) -> None:
        self.apply_filter(msg.text)

    def apply_filter(self, text: str) -> bool:
        """Apply a display filter (empty: none). False, with the error shown in the bar, if it does not compile."""
        bar = self.filter_bar
        if not text:
            self.workers.cancel_group(self, "filter")
            self.display_filter = None
            bar.clear_error()
            bar.set_applied(False)
            self.status.shown = None
            self.status.filtering = None
            self.status.update_status()
            self.packet_list.set_view(None, keep_row=self.packet_list.cursor_row)
            self._focus(self.packet_list)
            return True
        try:
            flt = compile_filter(text, self.dialect)
        except FilterError as exc:
            bar.show_error(exc.message, exc.position, exc.length)
            return False
        bar.clear_error()
        bar.set_applied(True)
        self.display_filter = flt
        self._start_filter(flt, keep_row=self.packet_list.cursor_row)
        self._focus(self.packet_list)
        return True

    def _start_filter(self, flt: DisplayFilter, keep_row: int | None) -> None:
        self._keep_row = keep_row
        self._filter_view_set = False
        self._filter_rows = rows = array("I")  # names this run: a cancelled run's late messages are ignored
        self.status.shown = 0
        self.status.filtering = 0.0
        self.status.update_status()
        self.run_filter(flt, self.index, rows)

    @work(thread=True, group="filter", exclusive=True, exit_on_error=False)
    def run_filter(self, flt: DisplayFilter, index: FrameIndex, rows: array) -> None:
        """Fill `rows` with the rows `flt` matches (following a live index as it grows)."""
        worker = get_current_worker()
        scan_filter(flt, index, rows, self.post_message, lambda: worker.is_cancelled)

    def on_filter_progress(self, msg: FilterProgress) -> None:
        if msg.flt is not self.display_filter or msg.rows is not self._filter_rows or self._torn_down():
            return
        pl = self.packet_list
        if not self._filter_view_set:
            self._filter_view_set = True
            pl.set_view(msg.rows, keep_row=self._keep_row)
        else:
            pl.sync()
        self.status.shown = pl.count
        self.status.filtering = None if msg.finished else msg.done / msg.total
        self.status.update_status()

    # --- screens ------------------------------------------------------------------------------

    def action_help(self) -> None:
        from mavscope.tui.screens.help import HelpScreen

        self.push_screen(HelpScreen())

    def action_keys(self) -> None:
        from mavscope.tui.screens.keys import KeyDialog

        self.push_screen(KeyDialog())

    def _analysis(self, module: str, screen: str) -> None:
        """Open an analysis screen over the rows in view (its module imported when first asked for)."""
        cls = getattr(importlib.import_module(f"mavscope.tui.screens.{module}"), screen)
        self.push_screen(cls(self.index, self._view()))

    def action_stats(self) -> None:
        self._analysis("stats", "StatsScreen")

    def action_mission(self) -> None:
        self._analysis("mission", "MissionScreen")

    def action_objects(self) -> None:
        self._analysis("objects", "ObjectsScreen")

    def action_expert(self) -> None:
        self._analysis("expert", "ExpertScreen")

    def action_events(self) -> None:
        self._analysis("events", "EventsScreen")

    def action_plot(self) -> None:
        """Plot the field under the detail tree's cursor (a number field of the payload or the header)."""
        from mavscope.tui.screens.plot import PlotScreen

        node = self.tree.cursor_node
        item = node.data if node is not None else None
        if item is None or item.generated:
            self.notify("select a field in the detail tree first (Enter on a frame, then move to the field)",
                        title="plot", severity="warning")
            return
        try:
            screen = PlotScreen(self.index, self._view(), item.name)
        except MavscopeError as exc:
            self.notify(visible(str(exc).removeprefix("plot: ")), title="plot", severity="warning", markup=False)
            return
        self.push_screen(screen)

    def _view(self) -> Sequence[int] | None:
        """The rows the screens analyse: the filtered view, or every frame."""
        view = self.packet_list.view
        return None if view is None else array("I", view)

    def goto_record(self, record: int) -> None:
        """Select the first frame of capture record `record` (from the expert, mission and objects screens)."""
        row = self.index.find_record(record)
        if row is None:
            return
        if self.display_filter is not None:
            self.apply_filter("")
            self.filter_bar.input.value = ""
        pl = self.packet_list
        pl.move_to(pl.position_of(row))
        pl.focus()

    # --- keys ---------------------------------------------------------------------------------

    def _keys_text(self) -> str:
        n = len(self.source.options.keys)
        c = len(self.source.options.ciphers)
        parts = []
        if n:
            parts.append(f"{n} signing key{'s' if n > 1 else ''}")
        if c:
            parts.append(f"{c} cipher{'s' if c > 1 else ''}")
        return ", ".join(parts) if parts else "no keys (k adds one)"

    def add_key(self, kind: str, spec: str) -> str | None:
        """Add a signing key (`kind` "key") or cipher ("cipher") as the command line's --key/--cipher
        would, and re-check the capture with it. Returns an error message, or None when accepted."""
        opts = self.source.options
        options = (replace(opts, keys=opts.keys + (spec,)) if kind == "key"
                   else replace(opts, ciphers=opts.ciphers + (spec,)))
        if isinstance(self.source, LiveFrameSource):
            index = self.index
            try:
                self.source.add_keys(options, index, lambda n: self.post_message(Rejudged(index, n)))
            except MavscopeError as exc:
                return str(exc)
        else:
            source = self.source.with_options(options)
            try:
                source.check()
            except MavscopeError as exc:
                return str(exc)
            self.source = source
            self.workers.cancel_group(self, "rebuild")
            if self.pending is not None:
                self.pending.close()
            self.pending = FrameIndex(self.dialect, self.source.path)
            self.rebuild_index(self.pending, source)
        self.keys_added.append(kind)
        self.status.keys = self._keys_text()
        self.status.activity = "re-checking with the new key"
        self.status.update_status()
        return None


def create_app(path: str | os.PathLike[str] | None, options: TuiOptions | None = None) -> MavscopeApp:
    """The TUI over the capture `path` (None with `options.live`: follow the UDP port `options.udp`).

    Raises CaptureError (missing, unreadable file) or UsageError (bad options) before anything is drawn.
    """
    options = options or TuiOptions()
    dialect = load_dialect(options.pipeline.dialects)
    if options.live:
        source: FrameSource = LiveFrameSource(options.udp or "14550", options.pipeline, dialect)
        source.check()
        index = FrameIndex(dialect, None)
        index.limit = options.keep
        return MavscopeApp(source, index)
    if path is None:
        raise MavscopeError("tui: a capture file or --live --udp PORT is needed")
    spath = os.fspath(path)
    source = FrameSource(spath, options.pipeline, dialect)
    source.check()
    return MavscopeApp(source, FrameIndex(dialect, spath))
