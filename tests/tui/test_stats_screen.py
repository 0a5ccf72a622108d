"""The statistics screen explains a ground station's loss in a tlog as `mavscope stats` does (issue 35 item 15).

A tlog holds what the ground station that wrote it received: its own frames only in part, so the numbers
missing from a ground station's sequence there are not link loss. `stats` marks such a link (`*`) and says
why under its Links table; the screen shows the same marks and the same line, from the same computation
(compute_stats with the Expert's logged_in_part), and does not colour that loss as an alarm.

The flow, built here with pymavlink (tests/support/flows.py): a vehicle 1/1 (HEARTBEAT type quadrotor)
numbering 100 frames 0..99, of which 40, 41 and 42 never reach the file; a ground station 255/190
(HEARTBEAT type GCS, MAV_TYPE_GCS = 6, every 10th frame, MANUAL_CONTROL otherwise) numbering 100 frames
0..99, of which 20..29 and 55 are not in the file. Expected, by hand from those numbers: the vehicle misses
3 numbers of 100 (3.00 %) and is no ground station, so its loss is link loss, unmarked; the ground station
misses 10 + 1 = 11 numbers of 100 (11.00 %), and in a tlog that is "logged in part" (marked, explained);
the same frames captured on the wire (a UDP pcap) are no recording: both links' gaps are loss, unmarked.
"""

from __future__ import annotations

from pathlib import Path

from rich.text import Text
from textual.widgets import DataTable, Label

from mavscope.tui.app import create_app
from mavscope.tui.verdicts import DIM, ORANGE, RED
from tests.conftest import Cli
from tests.support import flows
from tests.support.tui import SIZE, open_analysis, ready, run

VEHICLE_LOST = {40, 41, 42}
GCS_LOST = set(range(20, 30)) | {55}
PURE = {"MAVSCOPE_PURE": "1"}


def _entries() -> list[tuple[float, bytes]]:
    vehicle, gcs = flows.Sender(1, 1), flows.Sender(255, 190)
    out = []
    for i in range(100):
        v = vehicle.pack(flows.heartbeat())
        g = gcs.pack(flows.heartbeat(gcs=True) if i % 10 == 0 else flows.manual_control(x=i))
        if i not in VEHICLE_LOST:
            out.append((flows.T0 + i * 0.1, v))
        if i not in GCS_LOST:
            out.append((flows.T0 + i * 0.1 + 0.05, g))
    return out


def _links(path: str) -> tuple[dict[str, list[Text]], str | None]:
    """The Links table's rows (by Sys/Comp) and the line under it (None when it is not shown)."""
    rows: dict[str, list[Text]] = {}
    note: list[str | None] = [None]

    async def scenario() -> None:
        app = create_app(path)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await open_analysis(pilot, "s")
            links = app.screen.query_one("#links", DataTable)
            for i in range(links.row_count):
                cells = [c if isinstance(c, Text) else Text(str(c)) for c in links.get_row_at(i)]
                rows[cells[0].plain] = cells
            label = app.screen.query_one("#links-note", Label)
            note[0] = str(label.content) if label.display else None

    run(scenario())
    return rows, note[0]


def test_a_ground_stations_loss_in_a_tlog_is_marked_and_explained_as_stats_says(cli: Cli, tmp_path: Path) -> None:
    path = flows.write_tlog(tmp_path, _entries())
    rows, note = _links(path)
    gcs, vehicle = rows["255/190"], rows["1/1"]
    # columns: Sys/Comp, Received, Lost, Loss, ...
    assert [c.plain for c in gcs[1:4]] == ["89", "11*", "11.00 %*"]
    assert gcs[3].style == DIM  # explained, not the red of 11 % link loss
    assert [c.plain for c in vehicle[1:4]] == ["97", "3", "3.00 %"]
    assert vehicle[3].style == ORANGE  # the vehicle's gaps are link loss, coloured as such
    assert note is not None and note.startswith("* 255/190: ground station (HEARTBEAT type GCS) in a tlog")
    # the very line `stats` prints under its Links table, on both engines
    for environ in ({}, PURE):
        status, out, _ = cli("stats", path, environ=environ)
        assert status == 0 and note in out.splitlines()


def test_the_same_frames_on_the_wire_are_link_loss(tmp_path: Path) -> None:
    pcap = flows.write_udp_pcap(tmp_path / "flow.pcap", [
        (("10.0.0.2", 14550) if f[5:7] == b"\xff\xbe" else ("10.0.0.1", 14555),
         ("10.0.0.1", 14555) if f[5:7] == b"\xff\xbe" else ("10.0.0.2", 14550), f) for _, f in _entries()])
    rows, note = _links(str(pcap))
    gcs = rows["255/190"]
    assert [c.plain for c in gcs[1:4]] == ["89", "11", "11.00 %"] and gcs[3].style == RED
    assert note is None
