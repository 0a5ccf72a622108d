"""TUI figures on a large generated capture: time to the first rows, full index time, memory.

    python benchmarks/bench_tui.py [RECORDS]      # default 1,000,000 records (about 1.1M frames)
    python benchmarks/bench_tui.py --big [--copies 10] [--repeat 3] [--out DIR] [--app]
                                                  # the 10M-frame figures of issue 12 (native engine)

Generates the capture in a temporary directory (px4_sitl_udp.pcap's records repeated), then
1. builds the FrameIndex alone (no UI): first batch, full build, bytes per frame, RSS;
2. runs the app headless (Textual's Pilot) and reads `first_rows_at` / `indexed_at` off it;
3. compares with Textual's DataTable: the time to add 100k rows (why the packet list is a Line API widget);
4. times FrameIndex.rejudge over the whole index (what a key added in the live TUI costs per kept frame).

With --big: the 1M-frame bench pcap (benchmarks/out/bench_1000000_v2.pcap) `--copies` times behind one pcap
header (10,000,000 frames, as native_stats.py makes it), indexed natively (mavscope.native.index): time to
the first rows (the first progress callback), to the whole index (every row navigable), bytes per frame;
then display filters over the 10M rows through the column filter (mavscope.browse.fastfilter), best of
`--repeat` each; with --app, the app's own first-rows and indexed times on that capture.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mavscope.browse.fastfilter import ColumnFilter  # noqa: E402
from mavscope.browse.index import FrameIndex  # noqa: E402
from mavscope.capture.detect import open_capture  # noqa: E402
from mavscope.filter import compile_filter  # noqa: E402
from mavscope.mavlink.dialect import load_dialect  # noqa: E402
from mavscope.native.index import native_build  # noqa: E402
from mavscope.pipeline.dissect import Dissector  # noqa: E402
from mavscope.pipeline.options import PipelineOptions  # noqa: E402
from mavscope.pipeline.session import make_security_stage  # noqa: E402
from mavscope.security.stage import NOTE_CODES  # noqa: E402
from tests.support.tui import write_big_capture  # noqa: E402


def rss_anon_mb() -> float:
    for line in open("/proc/self/status"):
        if line.startswith("RssAnon:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def bench_index(path: Path) -> None:
    dialect = load_dialect()
    before = rss_anon_mb()
    t0 = time.perf_counter()
    first: list[float] = []
    index = FrameIndex(dialect, path)
    with open_capture(path) as reader:
        index.build(Dissector(dialect).run(reader), position=lambda: reader.position, total=reader.size,
                    on_progress=lambda p: first or first.append(time.perf_counter() - t0))
    full = time.perf_counter() - t0
    n = len(index)
    print(f"index alone: {n:,} frames; first batch after {first[0] * 1000:.0f} ms; complete after {full:.2f} s "
          f"({full / n * 1e6:.2f} µs/frame)")
    print(f"index memory: {index.memory() / 1e6:.1f} MB ({index.memory() / n:.0f} bytes/frame); "
          f"process anonymous RSS grew {rss_anon_mb() - before:.0f} MB")
    t = time.perf_counter()
    for i in range(0, n, max(1, n // 1000)):
        index.detail(i)
    print(f"detail (frame + decode + tree + summary), 1000 random rows: {(time.perf_counter() - t):.3f} s")
    stage = make_security_stage(PipelineOptions(keys=("passphrase:mavscope-demo",)))
    t = time.perf_counter()
    judged = index.rejudge(stage.run, NOTE_CODES)
    took = time.perf_counter() - t
    print(f"rejudge (a key added in the live TUI): {judged:,} frames in {took:.2f} s "
          f"({took / judged * 1e6:.1f} µs/frame)")
    index.close()


def bench_app(path: Path) -> None:
    from mavscope.tui.app import create_app

    async def scenario() -> None:
        app = create_app(path)
        async with app.run_test(size=(140, 45)) as pilot:
            while app.indexed_at is None:
                await pilot.pause(0.05)
            print(f"app: first rows on screen after {app.first_rows_at * 1000:.0f} ms; index complete after "
                  f"{app.indexed_at:.2f} s; {len(app.index):,} frames")
            t = time.perf_counter()
            for _ in range(20):
                await pilot.press("pagedown")
            await pilot.press("end")
            await pilot.pause()
            print(f"app: 20 PageDown + End: {time.perf_counter() - t:.2f} s")

    asyncio.run(scenario())
    print(f"max RSS of the process: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB "
          "(includes the memory-mapped capture)")


def bench_datatable(rows: int = 100_000) -> None:
    from textual.app import App
    from textual.widgets import DataTable

    class T(App[None]):
        def compose(self):  # type: ignore[no-untyped-def]
            yield DataTable()

    async def scenario() -> None:
        app = T()
        async with app.run_test() as pilot:
            table = app.query_one(DataTable)
            table.add_columns(*"abcdefgh")
            t = time.perf_counter()
            table.add_rows([(str(i), "0.000000", "127.0.0.1:14580", "1/1", "1", "ATTITUDE", "✓", "roll=0")
                            for i in range(rows)])
            await pilot.pause()
            print(f"DataTable: adding {rows:,} rows took {time.perf_counter() - t:.2f} s")

    asyncio.run(scenario())


BIG_FILTERS = ("mavlink.sysid == 1", "HEARTBEAT", "mavlink.msgname == GLOBAL_POSITION_INT",
               "signature.status == no-key", "mavlink.sysid == 1 && !ATTITUDE", "frame.time > 1700000100",
               "GLOBAL_POSITION_INT.relative_alt > 10000", "HEARTBEAT.type == MAV_TYPE_GCS")


def bench_big(args: argparse.Namespace) -> None:
    path, repeat = args.bench, args.repeat
    from benchmarks.native_stats import pcap_times

    dialect = load_dialect()
    folder = Path(tempfile.gettempdir()) / "mavscope-big"
    folder.mkdir(exist_ok=True)
    big = pcap_times(path, folder / f"bench_x{args.copies}.pcap", args.copies) if args.copies > 1 else path
    print(f"capture: {big} ({big.stat().st_size / 1e6:.0f} MB); load average {os.getloadavg()}")
    best_first = best_full = float("inf")
    index: FrameIndex | None = None
    for _ in range(repeat):
        if index is not None:
            index.close()
        before = rss_anon_mb()
        first: list[float] = []
        t0 = time.perf_counter()
        index = FrameIndex(dialect, big)
        native_build(index, str(big), dialect, make_security_stage(PipelineOptions()),
                     on_progress=lambda p: first or first.append(time.perf_counter() - t0))
        full = time.perf_counter() - t0
        best_first, best_full = min(best_first, first[0]), min(best_full, full)
        grew = rss_anon_mb() - before
    assert index is not None
    n = len(index)
    print(f"native index: {n:,} frames; first rows after {best_first * 1000:.1f} ms; complete (every row navigable) "
          f"after {best_full:.2f} s ({best_full / n * 1e9:.0f} ns/frame), best of {repeat}")
    print(f"index memory: {index.memory() / 1e6:.0f} MB ({index.memory() / n:.1f} bytes/frame); anonymous RSS grew "
          f"{grew:.0f} MB")
    t = time.perf_counter()
    for i in range(0, n, max(1, n // 1000)):
        index.detail(i)
    print(f"detail of 1000 rows spread over the index: {(time.perf_counter() - t) * 1000:.0f} µs each")
    for text in BIG_FILTERS:
        flt = compile_filter(text, dialect)
        best = float("inf")
        for _ in range(repeat):
            fast = ColumnFilter(flt, index)
            t = time.perf_counter()
            hits = sum(len(h) for _, h in fast.scan(0, n))
            best = min(best, time.perf_counter() - t)
        print(f"filter {text!r}: {hits:,} rows in {best:.2f} s (best of {repeat}; {fast.frames_tested:,} frames "
              "rebuilt)")
    print(f"load average after: {os.getloadavg()}")
    index.close()
    if args.app:
        bench_app(big)


def main(args: argparse.Namespace) -> None:
    if args.big:
        bench_big(args)
        return
    records = args.records
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.pcap"
        t = time.perf_counter()
        write_big_capture(path, records)
        print(f"generated {records:,} records ({path.stat().st_size / 1e6:.0f} MB) in {time.perf_counter() - t:.1f} s")
        bench_index(path)
        bench_app(path)
    bench_datatable()


def parse() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("records", nargs="?", type=int, default=1_000_000)
    ap.add_argument("--big", action="store_true", help="the 10M-frame figures (native index, column filter)")
    ap.add_argument("--bench", type=Path, default=Path(__file__).parent / "out" / "bench_1000000_v2.pcap")
    ap.add_argument("--copies", type=int, default=10)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--app", action="store_true", help="with --big: the app's own times too")
    return ap.parse_args()


if __name__ == "__main__":
    main(parse())
