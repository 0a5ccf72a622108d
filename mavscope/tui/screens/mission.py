"""`m`: mission, fence and rally transfers and the other mission operations, the waypoint table of the
chosen transfer, and a plot of the track.

The reconstruction is mavscope.analysis.mission's (`mavscope mission`); only the frames it reads (mission
messages, MISSION_CURRENT, HEARTBEAT, HOME_POSITION) and GLOBAL_POSITION_INT are rebuilt from the index
(picked by message id from its columns).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Label

from mavscope.analysis.mission import TRACKED_MESSAGES, Event, Transfer, analyse, event_text, pick
from mavscope.analysis.mission.describe import run_text
from mavscope.analysis.selection import Selection
from mavscope.mavlink.frame import Frame, decode_payload
from mavscope.mavlink.semantics import float_text, is_global
from mavscope.output.console import text
from mavscope.output.tables import coord_text
from mavscope.tui.screens.analysis import AnalysisScreen, first_rows
from mavscope.tui.verdicts import GREEN, ORANGE, RED
from mavscope.tui.widgets.track_plot import TrackPlot
from mavscope.tui.widgets.words import Table, Title

MAX_TRACK_POINTS = 4000


@dataclass
class MissionResult:
    transfers: list[Transfer]
    events: list[Event]
    track: list[tuple[float, float]]


def _fmt(v: float, float32: bool = True) -> str:
    """A parameter or coordinate: a float32 (`float32`) as the shortest text that reads back as the same
    float32, another float as repr (MISSION_ITEM_INT's local x/y in metres)."""
    return float_text(v, float32) if isinstance(v, float) else str(v)


class MissionScreen(AnalysisScreen):
    TITLE_TEXT = "Mission"
    DEFAULT_CSS = """
    MissionScreen #mission-left { width: 3fr; }
    MissionScreen #mission-right { width: 2fr; border-left: solid $primary-darken-2; }
    MissionScreen #transfers { height: auto; max-height: 8; }
    MissionScreen #items { height: 1fr; }
    MissionScreen Label { padding: 0 1; text-style: bold; }
    """

    def compose_body(self) -> ComposeResult:
        with Horizontal():
            with Vertical(id="mission-left"):
                yield Title("Transfers and operations (Enter: show a transfer's items)", id="transfers-title")
                yield Table(id="transfers", cursor_type="row", zebra_stripes=True)
                yield Title("Items", id="items-title")
                yield Table(id="items", cursor_type="row", zebra_stripes=True)
            with Vertical(id="mission-right"):
                yield Title("Track (blue: GLOBAL_POSITION_INT; orange: waypoints in order)")
                yield TrackPlot(id="plot")

    def analyse(self, frames: Iterator[Frame], selection: Selection) -> MissionResult:
        """Over the mission frames of the whole index (picked by the msgid column, without rebuilding the
        other frames); under a filter, the transfers with a frame in the view."""
        index = self.index
        dialect = index.dialect
        ids = {md.id for name, md in dialect.by_name.items() if name in TRACKED_MESSAGES}
        gpi = dialect.by_name.get("GLOBAL_POSITION_INT")
        gpi_id = gpi.id if gpi is not None else -1
        rows = index.rows()
        mission_rows = []
        track_rows = []
        for r, m in zip(rows, index.column("msgid", rows)):
            if m in ids:
                mission_rows.append(r)
            elif m == gpi_id:
                track_rows.append(r)
        log = analyse(index.frames(mission_rows), dialect)
        transfers, events = log.transfers, log.events
        if self.rows is not None:
            view = set(self.rows).intersection(mission_rows)
            shown = {rec for rec in index.column("record", sorted(view)) if rec is not None}
            transfers = [t for t in transfers if any(r in shown for r in t.frames)]
            events = [e for e in events if any(r in shown for r in e.frames)]
        step = max(1, len(track_rows) // MAX_TRACK_POINTS)
        track = []
        for frame in index.frames(track_rows[::step]):
            fields = decode_payload(frame)
            if fields and (fields.get("lat") or fields.get("lon")):
                track.append((int(fields["lat"]) / 1e7, int(fields["lon"]) / 1e7))  # type: ignore[call-overload]
        return MissionResult(transfers, events, track)

    def show(self, result: object) -> None:
        res: MissionResult = result  # type: ignore[assignment]
        table = self.query_one("#transfers", DataTable)
        table.add_columns("#", "Direction", "From", "To", "Type", "Items", "Result", "Frames")
        dialect = self.index.dialect
        mtypes = dialect.enums.get("MAV_MISSION_TYPE")
        transfers, cut = first_rows(res.transfers, "mission")
        events, events_cut = first_rows(res.events, "mission")
        for i, t in enumerate(transfers):
            style = GREEN if t.complete else (ORANGE if t.outcome in ("unacknowledged", "abandoned") else RED)
            mtype = (mtypes.name_of(t.mission_type) if mtypes else None) or str(t.mission_type)
            table.add_row(str(i + 1), t.direction, f"{t.sender[0]}/{t.sender[1]}",
                          f"{t.receiver[0]}/{t.receiver[1]}", mtype.replace("MAV_MISSION_TYPE_", ""),
                          f"{len(t.items)}/{t.count}", Text(t.reason, style=style),
                          f"{t.frames[0]}…{t.frames[-1]}" if t.frames else "", key=str(i))
        for i, ev in enumerate(events):
            mtype = (mtypes.name_of(ev.mission_type) if mtypes else None) or str(ev.mission_type)
            ok = ev.confirmed or (ev.ack is not None and ev.ack.result == 0)
            table.add_row("", ev.kind, f"{ev.sender[0]}/{ev.sender[1]}", f"{ev.target[0]}/{ev.target[1]}",
                          mtype.replace("MAV_MISSION_TYPE_", ""), "",
                          text(event_text(ev, dialect), style=GREEN if ok else ORANGE),
                          f"{ev.frames[0]}…{ev.frames[-1]}", key=f"e{i}")
        if not res.transfers:
            self.query_one("#items-title", Label).update("Items: no mission transfer in these frames")
        if cut or events_cut:
            self.query_one("#transfers-title", Label).update(
                f"Transfers{cut} and operations{events_cut} (Enter: show a transfer's items)")
        chosen = [i for i in (pick(transfers, 0), pick(transfers, 1), pick(transfers, 2)) if i is not None]
        best = chosen[0] if chosen else len(transfers) - 1
        if best >= 0:
            table.move_cursor(row=best)
            self.show_transfer(best)
        else:
            self.query_one(TrackPlot).set_data(res.track, [])
        self.query_one("#items", DataTable).focus()

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        key = event.row_key.value
        if event.data_table.id == "transfers" and key is not None and not key.startswith("e"):
            self.show_transfer(int(key))

    def show_transfer(self, i: int) -> None:
        res: MissionResult = self.result  # type: ignore[assignment]
        t = res.transfers[i]
        dialect = self.index.dialect
        cmds = dialect.enums.get("MAV_CMD")
        frames = dialect.enums.get("MAV_FRAME")
        table = self.query_one("#items", DataTable)
        table.clear(columns=True)
        table.add_columns("Seq", "Command", "Latitude", "Longitude", "Altitude", "Parameters", "Frame", "Frames")
        waypoints = []
        seqs, cut = first_rows(sorted(t.items), "mission")
        for seq in seqs:
            it = t.items[seq]
            name = (cmds.name_of(it.command) if cmds else None) or str(it.command)
            labels = {idx: (label, units) for idx, label, units in dialect.command_params(it.command)}
            params = []
            for n, v in enumerate(it.params, 1):
                if n in labels:
                    label, units = labels[n]
                    params.append(f"{label} {_fmt(v)}{' ' + units if units else ''}")
                elif v and not (isinstance(v, float) and math.isnan(v)):
                    params.append(f"param{n} {_fmt(v)}")
            glob = is_global(it.frame)
            wire_float = it.message != "MISSION_ITEM_INT"
            lat = coord_text(it.x, "°", wire_float) if glob else _fmt(it.x, wire_float)
            lon = coord_text(it.y, "°", wire_float) if glob else _fmt(it.y, wire_float)
            z_label = labels.get(7, ("Altitude", "m"))
            alt = f"{_fmt(it.z)} {z_label[1] or 'm'}"
            fname = (frames.name_of(it.frame) if frames else None) or str(it.frame)
            table.add_row(str(seq), name.replace("MAV_CMD_", ""), lat, lon, alt, ", ".join(params),
                          fname.replace("MAV_FRAME_", ""), ", ".join(map(str, it.frames[:4])))
            if glob and (it.x or it.y) and it.command < 100:  # NAV commands with a position
                waypoints.append((seq, it.x, it.y))
        title = f"Items of transfer {i + 1}: {t.direction} {t.sender[0]}/{t.sender[1]} → " \
                f"{t.receiver[0]}/{t.receiver[1]}, {len(t.items)} of {t.count}"
        missing = t.missing
        if missing:
            more = f" and {len(missing) - 8:,} more runs" if len(missing) > 8 else ""
            title += f", missing {run_text(missing[:8])}{more}"
        title += f": {t.reason}{cut}"
        self.query_one("#items-title", Label).update(title)
        self.query_one(TrackPlot).set_data(res.track, waypoints)
