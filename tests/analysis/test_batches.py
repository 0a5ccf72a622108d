"""Frames in column batches (pipeline/batch.py) give the answers frames one by one give.

The reference is the per-frame code that the batch paths call for their exceptions: `SeqChannels.feed`
(a frame at a time, the rules of analysis/sequence.py) and `Expert.add`. With batches of one frame every
step goes through that code; with larger batches the common steps are counted per column. So each test
runs the same frames through batches of several sizes (1, odd sizes, the default) and through the
per-frame calls, and requires identical steps, tracker state, statistics and findings. The native
walker's windows (pipeline/windows.py) must give the columns and Frames the Python pipeline gives.
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest

from mavscope.analysis import expert_batch
from mavscope.analysis import stats as stats_module
from mavscope.analysis.expert import Expert
from mavscope.analysis.sequence import SeqChannels, SeqTracker
from mavscope.analysis.sequence_batch import STEP_NAMES, feed_batch
from mavscope.analysis.stats import compute_stats
from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, new_frame
from mavscope.pipeline.batch import FrameBatch, Tables
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import open_session
from tests.conftest import CAPTURES

BUNDLED = sorted(p for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))


def _state(tr: SeqTracker) -> tuple[object, ...]:
    return (tr.last, tr.lost, tr.duplicates, tr.repeats, tr.unchanged, tr.reordered, tr.resets, tr.position,
            tr.newest, bytes(tr.missing) if tr.missing is not None else None, tr.large_gaps, tr.run, tr.run_seq,
            tr.last_raw, tr.shared, tr.full_steps, tr.gap_steps, tr.partner, tr.first_full, tr.at,
            [(g.record, g.before, g.after, g.size, g.remaining, g.shared) for g in tr.gaps])


def _seqs_state(seqs: SeqChannels) -> list[tuple[object, ...]]:
    return [(sender, ends, _state(tr)) for sender, chans in seqs.senders.items() for ends, tr in chans.items()]


def _batched_steps(frames: Sequence[Frame], sizes: Sequence[int]) -> tuple[list[str], SeqChannels]:
    seqs, tables, out, at, k = SeqChannels(), Tables(), [], 0, 0
    while at < len(frames):
        n = sizes[k % len(sizes)]
        k += 1
        steps = feed_batch(seqs, FrameBatch.of_frames(frames[at:at + n], tables))
        out += [STEP_NAMES[c] for c in steps.code.tolist()]
        at += n
    return out, seqs


def _frame(record: int, seq: int, sysid: int, compid: int, src: Endpoint | None, dst: Endpoint | None,
           payload: bytes) -> Frame:
    raw = bytes([0xFD, len(payload), 0, 0, seq, sysid, compid, 0, 0, 0]) + payload + b"\x00\x00"
    return new_frame(record, 1, float(record), "udp" if src is not None else "tlog", src, dst, None, raw, 2,
                     len(payload), 0, 0, seq, sysid, compid, 0, 0, CrcStatus.OK, None, None, (), None)


def _hostile_frames(seed: int, n: int = 6000) -> list[Frame]:
    """Senders on shared channels (more than a ring holds on one), senders on many channels, a second id on
    a counter (a shared counter), gaps, duplicates, copies with other contents, late frames, restarts."""
    rng = random.Random(seed)
    ends = [Endpoint(f"10.0.0.{i}", 14550) for i in range(1, 12)]
    gcs = Endpoint("10.0.0.200", 14550)
    senders = [(1, 1), (1, 2), (2, 1), (255, 190), (3, 1)] + [(10 + i, 1) for i in range(12)]
    counter = {s: rng.randrange(256) for s in senders}
    shared = 0
    frames: list[Frame] = []
    last: dict[tuple[int, int], Frame] = {}
    for record in range(1, n + 1):
        s = rng.choice(senders[:5] if rng.random() < 0.7 else senders)
        r = rng.random()
        if s == (1, 2):  # numbered on 1/1's counter (one program, two ids)
            counter[(1, 1)] = (counter[(1, 1)] + 1) % 256
            seq = counter[(1, 1)]
        elif r < 0.80:
            counter[s] = (counter[s] + 1) % 256
            seq = counter[s]
        elif r < 0.86:
            counter[s] = (counter[s] + rng.randrange(2, 140)) % 256
            seq = counter[s]
        elif r < 0.90 and s in last:
            frames.append(last[s]._replace(record=record))  # a copy, byte for byte
            continue
        elif r < 0.93:
            seq = counter[s]  # the same number, other contents
        elif r < 0.97:
            seq = (counter[s] - rng.randrange(1, 130)) % 256  # behind
        else:  # a restart: RESET_RUN frames in a row and more, from elsewhere
            start = rng.randrange(256)
            for k in range(12):
                f = _frame(record, (start + k) % 256, *s, ends[0], gcs, bytes([k, record & 255]))
                frames.append(f)
            counter[s] = (start + 11) % 256
            continue
        src = ends[rng.randrange(len(ends))] if s[0] >= 10 else ends[0] if rng.random() < 0.9 else ends[1]
        shared += 1
        f = _frame(record, seq, *s, src, gcs if rng.random() < 0.95 else None, bytes([record & 255, shared & 255]))
        last[s] = f
        frames.append(f)
    return frames


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_sequence_steps_in_batches_are_those_frame_by_frame(seed: int) -> None:
    frames = _hostile_frames(seed)
    ref = SeqChannels()
    expected = [ref.feed(f)[0] for f in frames]
    want_state = _seqs_state(ref)
    assert {"gap", "duplicate", "unchanged", "late", "reset"} <= set(expected)  # every kind of step is there
    for sizes in ([1], [4096], [97, 13, 500, 1], [2000, 48, 47]):
        got, seqs = _batched_steps(frames, sizes)
        assert got == expected, sizes
        assert _seqs_state(seqs) == want_state, sizes


def _capture_frames(path: Path) -> tuple[list[Frame], Dialect]:
    with open_session(str(path), PipelineOptions()) as s:
        return [f for f in s.items if type(f) is Frame], s.dialect


def _answers(frames: list[Frame], dialect: Dialect, batch: int, monkeypatch: pytest.MonkeyPatch) -> object:
    monkeypatch.setattr(stats_module, "BATCH", batch)
    expert = Expert(dialect)
    st = compute_stats(frames, expert)
    return (st.to_json(), [f.to_json() for f in expert.findings()], list(st.streams), list(st.conversations),
            {k: st.rate_series(k, 40) for k in st.streams})


def _per_frame_findings(frames: list[Frame], dialect: Dialect) -> list[dict[str, object]]:
    expert = Expert(dialect)
    for f in frames:
        expert.add(f)
    return [f.to_json() for f in expert.findings()]


def _real() -> list[Path]:
    root = CAPTURES.parent.parent / "shared" / "real-captures"
    return sorted(p for p in root.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw", ".bin")) \
        if root.is_dir() else []


@pytest.mark.parametrize("path", BUNDLED + _real(), ids=lambda p: p.name)
def test_statistics_and_findings_do_not_depend_on_the_batch(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Batches of 1 frame (every step through the per-frame code; the bundled captures) or 13 (the real
    ones, larger), 61 and 4096 frames; the findings also as `Expert.add` gives them frame by frame."""
    frames, dialect = _capture_frames(path)
    small = 1 if path.parent == CAPTURES else 13
    one = _answers(frames, dialect, small, monkeypatch)
    assert _answers(frames, dialect, 61, monkeypatch) == one
    assert _answers(frames, dialect, 4096, monkeypatch) == one
    assert one[1] == _per_frame_findings(frames, dialect)  # type: ignore[index]


def test_hostile_frames_through_the_expert_alike_in_batches(dialect: Dialect) -> None:
    frames = _hostile_frames(7, 3000)
    tables = Tables()
    expert = Expert(dialect)
    for at in range(0, len(frames), 211):
        expert_batch.feed(expert, FrameBatch.of_frames(frames[at:at + 211], tables))
    assert [f.to_json() for f in expert.findings()] == _per_frame_findings(frames, dialect)




@pytest.mark.parametrize("path", BUNDLED + _real(), ids=lambda p: p.name)
def test_native_windows_give_the_python_pipelines_batches(path: Path) -> None:
    """pipeline/windows.py (the C walker's column mode and the records it hands back) against the Python
    pipeline's frames: the same columns row for row, and the same Frames. Raw byte streams (.raw, .bin) too:
    the walker takes their clean stretches as rows (transport raw, each frame a record of its own) and hands
    back only the pieces around damage."""
    from mavscope.native import windows

    if not windows.available({}):
        pytest.skip("the C extension is not built")
    got: dict[bool, list[FrameBatch]] = {}
    for native in (False, True):
        with open_session(str(path), PipelineOptions(), environ={} if native else {"MAVSCOPE_PURE": "1"}) as s:
            got[native] = list(s.batches(lambda _item: None))
    columns = ("record", "time", "timed", "transport", "version", "seq", "sysid", "compid", "msgid", "size", "crc",
               "verdict", "signed", "clean")

    def joined(batches: list[FrameBatch], name: str) -> np.ndarray:
        return np.concatenate([getattr(b, name) for b in batches]) if batches else np.empty(0)

    for name in columns:
        assert joined(got[True], name).tolist() == joined(got[False], name).tolist(), name
    for key in ("label",):  # ids: compare what they name
        def names(batches: list[FrameBatch]) -> list[str]:
            return [b.tables.labels[i] for b in batches for i in getattr(b, key).tolist()]
        assert names(got[True]) == names(got[False])

    def texts(batches: list[FrameBatch], name: str) -> list[str]:
        return [b.tables.text(i) for b in batches for i in getattr(b, name).tolist()]

    assert texts(got[True], "src") == texts(got[False], "src") and texts(got[True], "dst") == texts(got[False], "dst")
    walked = [f for b in got[True] for f in b.frames(list(range(b.n)))]
    assert walked == [f for b in got[False] for f in b.frames(list(range(b.n)))]
