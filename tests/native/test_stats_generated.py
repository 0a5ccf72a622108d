"""Generated captures: `mavscope stats` on the native engine gives what the pure-Python path gives.

Hypothesis draws captures the analyses have something to say about (tests/native/stories.py: vehicles,
ground stations, commands, modes, positions, fixes, clocks, EKF reports, sequence numbers that skip,
repeat, come late or restart, signing senders, copies of earlier frames, handed-back records among them)
and the random captures and damaged files of test_generated.py. The native engine's batches and the
per-frame reference must give the same `--json` document, findings, stream and conversation order,
sparkline series and stderr; also in windows of 3 rows; a share runs through the command line (`--json`
and the text tables).
"""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from mavscope.mavlink.dialect import load_dialect
from tests.conftest import Cli
from tests.native.engines import KEY_OPTIONS, capture_file
from tests.native.stats_engines import native_stats_of, pure_stats
from tests.native.stories import story
from tests.native.test_generated import DAMAGED_FILES, FEWER, FEWEST, SETTINGS, capture
from tests.native.test_stats import FORMATS, same_stats

DIALECT = load_dialect()
KEYS = st.sampled_from(["none", "none", "key", "leaked"])
CLI = Cli()


def check(data: bytes, keys: str, small_window: bool = False) -> None:
    with capture_file(data) as path:
        pure = pure_stats(path, DIALECT, keys)
        native = native_stats_of(path, DIALECT, keys, limit=3 if small_window else None)
        assert native["stderr"] == pure["stderr"]
        assert native["json"] == pure["json"]
        assert native["findings"] == pure["findings"]
        assert native == pure


@SETTINGS
@given(story(), KEYS, st.integers(0, 4))
def test_story_is_identical(data: bytes, keys: str, window: int) -> None:
    check(data, keys, small_window=window == 0)


@FEWER
@given(capture(), KEYS)
def test_random_capture_is_identical(data: bytes, keys: str) -> None:
    check(data, keys)


@FEWER
@given(*DAMAGED_FILES)
def test_arbitrary_bytes_are_identical(tail: bytes, head: bytes) -> None:
    check(head + tail, "none")


@FEWEST
@given(st.one_of(story(), capture()), st.sampled_from(sorted(KEY_OPTIONS)), st.sampled_from(sorted(FORMATS)))
def test_through_the_command_line(data: bytes, keys: str, fmt: str) -> None:
    with capture_file(data) as path:
        same_stats(CLI, path, *KEY_OPTIONS[keys], *FORMATS[fmt])
