"""Replay detection's bounds (issue 35, item 1 for the expert's ReplayedCommands; docs/security.md, "Bounds").

- The frames remembered (COPIES_KEPT, 65,536): a flood of distinct command or setpoint frames once pushed the
  oldest out, so an ARM recorded before the flood and replayed after it was not reported, and nothing said
  so. Now the newest remembered but the one just seen goes (notes.pop_newest), said as a `capacity` finding
  that stats and audit report. The native pass hands the capture to the pure path at the bound.
- The copies held per channel until later frames place them (10 ahead of the counter, 10 behind): past
  them the oldest behind was dropped unjudged and a run ahead was judged in place. Now every copy is judged:
  the first 25 of a run with their frames (a finding lists 50 frame numbers, two a copy), the others
  counted per message. The native engine does the same (no hand-over).

Every expected answer is worked out by hand from the flow each test builds (its docstring says how), by the
definition of a replay in docs/analysis.md ("Replays"): a copy byte for byte behind its sender's counter
that the counter then runs on past, or ahead of it and reached again by the sender's own frames.
"""

from __future__ import annotations

import json
from pathlib import Path

from mavscope.analysis import replays
from mavscope.mavlink.dialect import load_dialect
from tests.analysis.test_replays import GCS, both
from tests.conftest import Cli
from tests.native.stats_engines import native_stats_of, pure_stats
from tests.support import flows

PURE, NATIVE = {"MAVSCOPE_PURE": "1"}, {"MAVSCOPE_PURE": "0"}
DIALECT = load_dialect()


def test_a_flood_of_distinct_setpoints_does_not_hide_a_replayed_arm(cli: Cli, tmp_path: Path) -> None:
    """Record 1: an ARM (COMMAND_LONG 400) from the GCS 255/190, sequence 0. Records 2-70001: 70,000
    MANUAL_CONTROL frames from 254/190, each with its own (x, y): no two alike. Record 70002: the ARM's bytes
    again, from 255/190 with sequence 0: the sequence number its counter already used, filling nothing
    (behind it), at the end of the capture: a replay, listed with its original (frames 1 and 70002).

    What is given up, by hand: 65,536 frames are remembered; the ARM and flood frames 1-65,535 fill them;
    flood frames 65,536-70,000 (records 65,537-70,001) each forget the newest remembered but themselves:
    4,465 give-ups, said at the 1st, 2nd, 4th, ... 4,096th (records 65,536 + 1, 2, 4, ..., 4,096). The last
    said (give-up 4,096, record 69,632) forgot the frame added just before it, record 69,631. The old policy
    (oldest out) forgot the ARM at the first give-up, and the replay went unreported."""
    assert replays.COPIES_KEPT == 65_536
    gcs, flood = flows.Sender(*GCS), flows.Sender(254, 190)
    arm = gcs.pack(flows.command_long(400, 1.0))
    entries = [(flows.T0, arm)]
    entries += [(flows.T0 + 0.001 * (i + 1), flood.pack(flows.manual_control(x=i % 2000 - 1000, y=i // 2000)))
                for i in range(70_000)]
    entries.append((flows.T0 + 100, arm))
    path = flows.write_tlog(tmp_path, entries)
    said = [65_536 + (1 << k) for k in range(13)]

    doc = cli.json("stats", path, environ=PURE)
    (replay,) = [f for f in doc["findings"] if f["code"] == "replayed-command"]
    assert replay["frames"] == [1, 70_002] and "COMMAND_LONG 1" in replay["message"]
    (capacity,) = [f for f in doc["findings"] if f["code"] == "capacity"]
    assert capacity["frames"] == said
    assert capacity["message"].startswith(
        "replay detection's remembered command and setpoint frames (at most 65,536): 4,465 given up (4,465 "
        "frames); the last said: the frame of record 69631 forgotten for the one of record 69632")

    audit = cli("audit", path, "--json", environ=PURE)
    codes = {f["code"]: f["frames"] for f in json.loads(audit.out)["findings"]}
    assert codes["replayed-command"] == [1, 70_002] and codes["capacity"] == said and audit.status == 1
    # the batches (native windows) give the per-frame answers at the bound, and both engines say the same
    assert native_stats_of(path, DIALECT) == pure_stats(path, DIALECT)
    for argv in (("stats", path, "--json"), ("audit", path, "--json"), ("audit", path)):
        assert cli(*argv, environ=NATIVE) == cli(*argv, environ=PURE), argv


def test_thirty_copies_behind_the_counter_are_thirty_replays(cli: Cli, tmp_path: Path) -> None:
    """The GCS sends 400 frames, frame i with sequence i % 256 (tlog record i + 1): COMMAND_LONGs at the even i
    from 40 to 98 (30 of them, records 41, 43, ..., 99), MANUAL_CONTROL with x = i otherwise. Before its frame
    100 the 30 COMMAND_LONGs are sent again (records 101-130): each number is 1 to 59 behind the counter (at
    99) and, the numbers not consecutive, never a restarted counter: 30 copies behind it. The GCS's frame 100
    (record 131) then runs on from 99: all 30 are replays. The finding lists its first 50 frame numbers,
    (original, copy) in order: 41, 101, 43, 102, ..., 89, 125. The old bound (10 held behind, the oldest
    dropped) reported 10."""
    entries = flows.run_sent_again(flows.Sender(*GCS), lambda i: 40 <= i < 100 and i % 2 == 0, 100)
    path = flows.write_tlog(tmp_path, entries)
    (replay,) = both(cli, path)["replayed-command"]
    assert replay["message"].startswith("link 255/190: 30 command or setpoint frame(s)")
    assert "COMMAND_LONG 30" in replay["message"]
    assert replay["frames"] == [r for k in range(25) for r in (41 + 2 * k, 101 + k)]
    assert native_stats_of(path, DIALECT) == pure_stats(path, DIALECT)  # the batches as frame by frame


def test_a_run_of_thirty_copies_ahead_of_the_counter_is_thirty_replays(cli: Cli, tmp_path: Path) -> None:
    """The GCS sends 400 frames, frame i with sequence i % 256 (record i + 1): COMMAND_LONGs at i 40-69
    (records 41-70), MANUAL_CONTROL with x = i otherwise. After its frame 199 the 30 COMMAND_LONGs are sent
    again (records 201-230): 40 is 97 ahead of 199, a jump forward, and the copies follow it number by
    number up to 69. The GCS's own frames 200..295 fill the jump (late), and its frame 296 has number 40
    again before the counter passed the run: all 30 copies were ahead of the counter, replays. Listed:
    41, 201, 42, 202, ..., 65, 225. The old bound (10 held ahead) judged the run in place at its 11th copy:
    no replay at all."""
    entries = flows.run_sent_again(flows.Sender(*GCS), lambda i: 40 <= i < 70, 200)
    path = flows.write_tlog(tmp_path, entries)
    found = both(cli, path)
    (replay,) = found["replayed-command"]
    assert replay["message"].startswith("link 255/190: 30 command or setpoint frame(s)")
    assert replay["frames"] == [r for k in range(25) for r in (41 + k, 201 + k)]
    assert "capacity" not in found  # nothing given up
    assert native_stats_of(path, DIALECT) == pure_stats(path, DIALECT)
