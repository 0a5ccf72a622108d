"""`s`: message rates per stream with sparklines, loss per link, totals (mavscope.analysis.stats).

Loss as `mavscope stats` gives it, from the same computation (`compute_stats` with an Expert of the
detectors `Expert.logged_in_part` reads): a ground station's link in a tlog, whose own frames the tlog logs
only in part, has its lost numbers marked (`*`, no alarm colour) and the line `stats` prints under its Links
table says why.
"""

from __future__ import annotations

from collections.abc import Iterator

from rich.text import Text
from textual.app import ComposeResult
from textual.widgets import DataTable, Label

from mavscope.analysis.expert import LOGGED_IN_PART_DETECTORS, Expert
from mavscope.analysis.selection import Selection
from mavscope.analysis.stats import Stats, compute_stats
from mavscope.mavlink.frame import Frame
from mavscope.output.tables import PARTIAL_MARK, listed, partial_line, sparkline
from mavscope.tui.screens.analysis import AnalysisScreen, first_rows
from mavscope.tui.verdicts import DIM, GREEN, ORANGE, RED
from mavscope.tui.widgets.words import Table, Title

SPARK_WIDTH = 30


def _pct(v: float, part: bool = False) -> Text:
    """A link's loss; `part`: a link logged only in part (Stats.logged_in_part), marked and not coloured as loss."""
    if part:
        return Text(f"{v:.2f} %{PARTIAL_MARK}", style=DIM, justify="right")
    style = GREEN if v == 0 else (ORANGE if v < 5 else RED)
    return Text(f"{v:.2f} %", style=style, justify="right")


class StatsScreen(AnalysisScreen):
    TITLE_TEXT = "Statistics"
    DEFAULT_CSS = """
    StatsScreen DataTable { height: 1fr; }
    StatsScreen #links { height: auto; max-height: 12; }
    StatsScreen #links-note { display: none; }
    StatsScreen Label { padding: 0 1; text-style: bold; margin-top: 1; }
    """

    def compose_body(self) -> ComposeResult:
        yield Title("Loss per link (sequence gaps per sysid/compid)", id="links-title")
        yield Table(id="links", zebra_stripes=True, cursor_type="row")
        yield Title(id="links-note")  # shown when a link is logged in part (partial_line)
        yield Title("Message rates", id="rates-title")
        yield Table(id="rates", zebra_stripes=True, cursor_type="row")

    def analyse(self, frames: Iterator[Frame], selection: Selection) -> Stats:
        return compute_stats(frames, Expert(self.index.dialect, LOGGED_IN_PART_DETECTORS))

    def show(self, result: object) -> None:
        stats: Stats = result  # type: ignore[assignment]
        selection = self.selection
        links = self.query_one("#links", DataTable)
        links.add_columns("Sys/Comp", "Received", "Lost", "Loss", "Duplicates", "Reordered", "CRC", "Signature",
                          "Endpoints")
        link_rows, links_cut = first_rows(stats.links_json(selection), "stats")
        for lk in link_rows:
            crc = ", ".join(f"{k} {v}" for k, v in lk["crc"].items())  # type: ignore[attr-defined]
            sig = ", ".join(f"{k} {v}" for k, v in lk["signature"].items())  # type: ignore[attr-defined]
            part = bool(lk["logged_in_part"])
            links.add_row(f"{lk['sysid']}/{lk['compid']}", Text(f"{lk['received']:,}", justify="right"),
                          Text(f"{lk['lost']:,}" + (PARTIAL_MARK if part else ""), justify="right"),
                          _pct(lk["loss_pct"], part),  # type: ignore[arg-type]
                          Text(str(lk["duplicates"]), justify="right"), Text(str(lk["reordered"]), justify="right"),
                          crc, sig, listed(lk["endpoints"]))  # type: ignore[arg-type]
        note = self.query_one("#links-note", Label)
        partial = partial_line(link_rows)
        note.display = partial is not None
        if partial is not None:
            note.update(partial)
        rates = self.query_one("#rates", DataTable)
        duration = stats.duration
        rates.add_columns("Sys/Comp", "Message", "Count", "Rate", "Bytes",
                          f"Frames per second over {duration or 0:.0f} s")
        message_rows, messages_cut = first_rows(stats.messages_json(selection), "stats")
        for m in message_rows:
            key = (m["sysid"], m["compid"], m["msgname"])
            rate = "burst" if m["burst"] else ("-" if m["rate_hz"] is None else f"{m['rate_hz']:.2f} Hz")
            rates.add_row(f"{m['sysid']}/{m['compid']}", m["msgname"], Text(f"{m['count']:,}", justify="right"),
                          Text(rate, justify="right"),
                          Text(f"{m['bytes']:,}", justify="right"),
                          Text(sparkline(stats.rate_series(key, SPARK_WIDTH)), style="cyan"))  # type: ignore[arg-type]
        t = stats.totals_json()
        self.query_one("#rates-title", Label).update(
            f"Message rates: {t['frames']:,} frames, {t['bytes']:,} bytes over {duration or 0:.1f} s, "
            f"{t['links']} links, {t['messages']} message types{messages_cut}")
        if links_cut:
            self.query_one("#links-title", Label).update(f"Loss per link (sequence gaps per sysid/compid){links_cut}")
        rates.focus()
