"""`o`: objects moved over the link (mavscope.analysis.objects, as `mavscope objects`): files read and
written over MAVLink FTP, listings, logs, images. The table lists them; the pane below shows the one
under the cursor (sha256, gaps, frames, signature verdicts, problems) and the start of its bytes, as text
when they are text, else in hex. Enter jumps to the object's first frame.

Only the frames the reconstruction reads (FILE_TRANSFER_PROTOCOL, LOG_*, DATA_TRANSMISSION_HANDSHAKE,
ENCAPSULATED_DATA) are rebuilt from the index, picked by message id from its columns.
"""

from __future__ import annotations

from collections.abc import Iterator

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import VerticalScroll
from textual.widgets import DataTable, Label, Static

from mavscope.analysis.objects import TRACKED_MESSAGES, ObjectLog, ObjectRecord, ObjectTracker, party
from mavscope.analysis.selection import Selection
from mavscope.mavlink.frame import Frame
from mavscope.output.console import text as escaped
from mavscope.tui.screens.analysis import AnalysisScreen, first_rows
from mavscope.tui.verdicts import GREEN, ORANGE, RED
from mavscope.tui.widgets.words import Pane, Table, Title
from mavscope.visible import visible

PREVIEW_BYTES = 2048


def state(r: ObjectRecord) -> Text:
    if r.complete:
        return Text("complete", style=GREEN)
    missing = sum(b - a for a, b in r.gaps)
    unit = "entries" if r.gap_unit == "entries" else "bytes"
    text = f"gaps: {missing:,} {unit}" if r.gaps else "incomplete"
    return Text(text if r.end_known else text + ", end unknown", style=ORANGE)


def preview(data: bytes) -> Text:
    """The start of an object: as text if it is printable UTF-8, else as a hex dump."""
    head = data[:PREVIEW_BYTES]
    try:
        text = head.decode("utf-8")
        if all(c.isprintable() or c in "\n\t" for c in text):  # (a CR would rewrite the line: hex)
            return Text(text + ("\n…" if len(data) > PREVIEW_BYTES else ""))
    except UnicodeDecodeError:
        pass
    lines = [f"{off:08x}  {head[off:off + 16].hex(' '):<47}  "
             f"{''.join(chr(b) if 32 <= b < 127 else '.' for b in head[off:off + 16])}"
             for off in range(0, min(len(head), 512), 16)]
    if len(data) > 512:
        lines.append("…")
    return Text("\n".join(lines))


def describe(r: ObjectRecord) -> Text:
    sigs = "; ".join(f"{who}: " + ", ".join(f"{k} {n}" for k, n in v.items()) for who, v in r.signatures.items())
    gaps = ", ".join(f"{a}-{b}" for a, b in r.gaps[:8]) + (" …" if len(r.gaps) > 8 else "")
    lines = [f"{r.kind} {r.direction} {r.path or r.name}: {party(r.sender)} → {party(r.receiver)}",
             f"{r.size:,} bytes" + (f" (announced {r.announced_size:,})" if r.announced_size is not None else "")
             + f", sha256 {r.sha256}",
             f"frames {r.frame_count} ({r.first_frame}…{r.last_frame}); signatures {sigs or '-'}"]
    if r.gaps:
        lines.append(f"missing ({r.gap_unit}): {gaps}")
    if r.duplicate_bytes or r.conflict_bytes:
        lines.append(f"received again: {r.duplicate_bytes:,} bytes the same, {r.conflict_bytes:,} different")
    lines += [f"! {p}" for p in r.problems]
    return Text(visible("\n".join(lines), keep_newlines=True), style=RED if r.conflict_bytes else "")


class ObjectsScreen(AnalysisScreen):
    TITLE_TEXT = "Objects"
    DEFAULT_CSS = """
    ObjectsScreen #objects { height: 1fr; }
    ObjectsScreen #object-pane { height: 1fr; border-top: solid $primary-darken-2; }
    ObjectsScreen Label { padding: 0 1; text-style: bold; }
    ObjectsScreen Static { padding: 0 1; }
    """

    def compose_body(self) -> ComposeResult:
        yield Title("Files (MAVLink FTP), logs and images (Enter: go to the first frame)", id="objects-title")
        yield Table(id="objects", cursor_type="row", zebra_stripes=True)
        with VerticalScroll(id="object-pane"):
            yield Pane(id="object-detail")
            yield Pane(id="object-preview")
            yield Pane(id="object-notes")

    def analyse(self, frames: Iterator[Frame], selection: Selection) -> ObjectLog:
        """Over the frames of the whole index that carry objects; under a filter, the objects with a frame
        in the view."""
        index = self.index
        dialect = index.dialect
        ids = {md.id for name, md in dialect.by_name.items() if name in TRACKED_MESSAGES}
        rows = index.rows()
        picked = [r for r, m in zip(rows, index.column("msgid", rows)) if m in ids]
        tracker = ObjectTracker()
        tracker.use_dialect(dialect)
        for f in index.frames(picked):
            tracker.feed(f)
        log = tracker.finish()
        if self.rows is not None:
            view = set(self.rows).intersection(picked)
            shown = {rec for rec in index.column("record", sorted(view)) if rec is not None}
            log.objects = [o for o in log.objects if any(n in shown for n in o.frames)]
            log.operations = [op for op in log.operations if op.frame in shown]
        return log

    def show(self, result: object) -> None:
        log: ObjectLog = result  # type: ignore[assignment]
        table = self.query_one("#objects", DataTable)
        table.add_columns("#", "Kind", "Path / name", "From → to", "Size", "State", "Frames", "Signed")
        listed, cut = first_rows(log.objects, "objects")
        for i, r in enumerate(listed):
            table.add_row(str(r.number), r.kind + (" ↓" if r.direction == "download" else " ↑"),
                          escaped(r.path or r.name), f"{party(r.sender)} → {party(r.receiver)}",
                          Text(f"{r.size:,}", justify="right"), state(r), f"{r.frame_count}",
                          "yes" if r.signed_frames else "no", key=str(i))
        title = f"{len(log.objects)} object(s), {sum(r.complete for r in log.objects)} complete{cut}"
        if not log.objects:
            title = "No file (MAVLink FTP), log or image in these frames"
        self.query_one("#objects-title", Label).update(title + "  (Enter: go to the first frame)")
        ops, ops_cut = first_rows(log.operations, "objects")
        notes = [f"FTP {op.opcode} {op.path or ''} from {party(op.client)}: {op.result or 'no answer'}"
                 f"{'; ' + op.detail if op.detail else ''} (frame {op.frame})" for op in ops]
        if ops_cut:
            notes.append(f"FTP operations{ops_cut}")
        notes += [f"[{f.severity.value}] {f.code}: {f.message}" for f in log.findings]
        if log.image_orphans:
            notes.append(f"{log.image_orphans} ENCAPSULATED_DATA frame(s) before any image was announced")
        self.query_one("#object-notes", Static).update(Text(visible("\n".join(notes), keep_newlines=True), style="dim"))
        if log.objects:
            self.show_object(0)
        table.focus()

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if event.row_key.value is not None and self.result is not None:
            self.show_object(int(event.row_key.value))

    def show_object(self, i: int) -> None:
        log: ObjectLog = self.result  # type: ignore[assignment]
        r = log.objects[i]
        self.query_one("#object-detail", Static).update(describe(r))
        self.query_one("#object-preview", Static).update(preview(r.data))

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        log: ObjectLog = self.result  # type: ignore[assignment]
        if event.row_key.value is None:
            return
        r = log.objects[int(event.row_key.value)]
        self.dismiss(None)
        self.app.goto_record(r.first_frame)  # type: ignore[attr-defined]
