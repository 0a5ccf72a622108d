"""The two test tiers (docs/testing.md, "Tiers"): what `make test` leaves to `make test-slow`, in one place.

`tests/conftest.py`'s `pytest_collection_modifyitems` calls `mark` on every collected test before `-m` selects:
- a test matching `SLOW` (fnmatch over its node id) gets the `slow` marker;
- a parametrized test named in `SWEEPS` keeps in the fast tier only the parametrizations whose id (the text in
  brackets) matches one of its patterns, and the others get `slow` (when no collected one matches, the first
  collected stays fast, so a renamed capture never takes the whole sweep out of `make test`);
- a property test (hypothesis) runs, under the `fast` hypothesis profile (the default), a tenth of the
  examples it asks for (`fast_examples`); `make test-slow` runs every property test again with all of them
  (`HYPOTHESIS_PROFILE=full`, `-m "slow or hypothesis"`).

`make test` = `-m "not slow"`, `make test-slow` = `-m "slow or hypothesis"`. Every test module keeps at least
one fast test except those in `WHOLLY_SLOW` (checked by tests/meta/test_tiers.py over a whole collection).
With `MAVSCOPE_TIER_REPORT=PATH` the tiers given are written to PATH as JSON (that check reads it).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable, Iterable, Sequence
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, is_hypothesis_test, settings

PROFILE_ENV = "HYPOTHESIS_PROFILE"
REPORT_ENV = "MAVSCOPE_TIER_REPORT"
FAST, FULL = "fast", "full"
EXAMPLES_DIVISOR = 10  # the fast tier runs max_examples // 10 of a property test's examples ...
EXAMPLES_FLOOR = 5  # ... and at least 5 (or all it asks for, when fewer)

# A capture sweep: a parametrized test whose parametrizations name SWEEP_CAPTURES or more of the bundled
# captures (captures/) and the real ones (../shared/real-captures) together. The fast tier keeps the
# parametrizations that name a representative: of the bundled captures `signed_udp.pcap` (signing, several
# senders) and `damaged.pcap` (every kind of damage), of the real ones the first of REAL_KEPT the sweep names
# (a small signed pcap, the smallest tlog, a raw stream); and those that name no capture.
SWEEP_CAPTURES = 4
BUNDLED_KEPT = ("signed_udp.pcap", "damaged.pcap")
REAL_KEPT = ("ap_sitl_attack1_signed_knownkey.pcap", "px4flow_v1_encapsulated_data.tlog",
             "px4_fw_mission_download_raw.bin", "ardusub_log_tools_small.tlog")
_ROOT = Path(__file__).resolve().parents[2]
_BUNDLED_CAPTURES, _REAL_CAPTURES = _ROOT / "captures", _ROOT.parent / "shared" / "real-captures"
_CAPTURE_SUFFIXES = {".pcap", ".pcapng", ".tlog", ".raw", ".bin"}

# Tests wholly in the slow tier: fnmatch patterns over the node id without its parametrization (every
# parametrization goes), or one node id exactly when it has brackets. Sweeps over every real capture in one
# test, scale tests (floods of senders, endpoints, groups or receivers past a bound, work that stays linear
# over large inputs), searches (a header checksum of 0 among 65,536 IP ids), regenerating every capture, mypy.
SLOW: tuple[str, ...] = (
    "tests/capture/test_stdin.py::test_a_long_stream_in_bounded_memory",  # 60 MB through a pipe, pure path
    "tests/capture/test_stdin.py::test_real_captures_on_a_pipe",  # three real captures, six processes
    "tests/export/test_sources.py::test_real_captures_in_small_windows",  # every real capture, 7-frame chunks
    "tests/native/test_raw_native.py::test_damage_at_the_chunk_boundary",  # 64 KiB streams, both engines
    "tests/native/test_raw_native.py::test_real_raw_captures",  # the real raw streams through the CLI
    "tests/meta/test_native_contract.py::test_the_contract_constants_have_one_definition",  # reads every source
    "tests/meta/test_lint.py::test_mypy_finds_nothing",  # the whole package type-checked: also `make lint`
    "tests/report/test_browser.py::test_nothing_is_fetched_and_nothing_fails",  # Chromium under DevTools
    "tests/report/test_browser.py::test_the_watch_sees_a_request",  # Chromium under DevTools
    "tests/report/test_browser.py::test_screenshots",  # two Chromium screenshots
    "tests/report/test_cli.py::test_a_long_capture_makes_a_short_page",  # 21,000 frames built and reported
    "tests/rules/test_real_captures.py::test_the_pack_on_every_real_capture",  # the pack over every real capture
    "tests/meta/test_tiers.py::test_every_module_keeps_a_fast_test_and_every_rule_names_tests",
    "tests/pipeline/test_captures_reproducible.py::test_regenerated_files_are_identical",
    "tests/pipeline/test_frame_numbers_after_holes.py::test_frame_numbers_are_unique_past_a_long_hole",
    "tests/transport/test_checksum_review.py::test_a_right_header_checksum_of_0_is_right",
    "tests/transport/test_defrag.py::test_reassembly_work_is_linear",
    "tests/mavlink/test_receiving_sockets.py::test_a_flood_of_*",
    "tests/mavlink/test_receiving_sockets.py::test_a_broadcast_half_outlives_a_flood_of_hosts_on_its_port",
    "tests/analysis/test_replay_bounds.py::test_a_flood_of_distinct_setpoints_does_not_hide_a_replayed_arm",
    "tests/analysis/test_analysis_caps.py::test_a_command_flood_gives_up_its_own_commands_and_says_so",
    "tests/analysis/test_analysis_caps.py::test_a_flood_of_senders_past_the_old_bound_does_not_hide_the_vehicle",
    "tests/analysis/test_crcextra_bounds.py::test_a_flood_of_groups_is_bounded_said_and_keeps_the_mismatch",
    "tests/analysis/test_stats.py::test_a_seq_tracker_with_gaps_is_small",
    "tests/native/test_stats_limits.py::test_more_senders_than_the_analyses_follow",
    "tests/native/test_stats.py::test_many_senders",
    "tests/native/test_signing_walk.py::test_bench_capture",
    "tests/export/test_sources.py::test_more_endpoints_than_the_walker_remembers",
    "tests/browse/test_index.py::test_large_capture_first_rows_before_the_index_completes[pure]",
    # every real capture in one test (each module keeps others on the real captures)
    "tests/native/test_stats.py::test_real_captures_through_the_api",
    "tests/export/test_sources.py::test_every_real_capture_gives_the_python_rows",
    "tests/export/test_dataset.py::test_real_captures_counts_per_message_link_and_verdict",
    "tests/export/test_native_findings.py::test_real_captures_leave_the_same_state",
    "tests/browse/test_fastfilter.py::test_real_captures",
    "tests/browse/test_native_index.py::test_real_captures",
    "tests/cli/test_command_params_shown.py::test_real_captures",
    "tests/cli/test_stdout_outputs.py::test_read_w_dash_on_real_captures",
    "tests/capture/test_tlog_cut_entries.py::test_real_tlogs_both_engines_and_what_the_c_parser_reads",
    # one large real capture read again (the module's other tests read the same ones)
    "tests/analysis/test_params_streams.py::test_plane_stream_rates_are_explained",
    "tests/analysis/test_params_real.py::test_rover_sets_confirmed",
    "tests/analysis/test_story_real.py::test_transition_counts",
    "tests/analysis/test_story_real.py::test_parameter_changes_no_set_explains",
    "tests/analysis/test_objects_png.py::test_px4flow_images_as_png",
    # variants of a replay on both engines, each in stats, audit and verify (the module keeps a copy ahead of the
    # counter, reordered copies, a signed command sent twice, a wrapping stream with loss)
    "tests/analysis/test_replays.py::test_a_recorded_run_sent_again_*_the_counter",
    "tests/analysis/test_replays.py::test_two_channels_with_their_own_counters",
    "tests/analysis/test_replays.py::test_a_dropout_longer_than_the_counter_is_not_a_replay",
    # every ordering of a mission exchange on both engines (test_transfers_are_what_the_parties_did keeps each)
    "tests/analysis/test_mission_orderings.py::test_every_ordering_is_the_same_on_both_engines",
    # long walks of the TUI through Pilot: every screen with hostile words (tests/cli/test_hostile_words.py and
    # the module's fast test keep the rule), the live follow mode's key and drop runs, the filter bar's error
    # positions, the key dialog's passes, the objects screen under a filter (each module keeps faster walks)
    "tests/tui/test_hostile_screens.py::test_every_screen_shows_hostile_words_escaped",
    "tests/tui/test_live_follow.py::test_a_key_added_while_live_judges_the_kept_frames_again_and_those_that_follow",
    "tests/tui/test_live_follow.py::test_follow_mode_survives_moving_and_filtering_while_rows_are_dropped",
    "tests/tui/test_app.py::test_filter_bar_apply_inline_error_at_the_position_and_escape",
    "tests/tui/test_app.py::test_key_dialog_adds_a_passphrase_and_the_verdicts_update",
    "tests/tui/test_objects_screen.py::test_objects_screen_under_a_filter_and_with_nothing_to_show",
    "tests/security/test_hostile_keys.py::test_the_key_dialog_masks_what_is_typed_and_its_error",
    # scale and floods on both engines (the modules keep a bound's smaller cases)
    "tests/native/test_stats_limits.py::test_commanders_sprayed_at_three_vehicles",
    "tests/native/test_stats_limits.py::test_copies_past_what_replayed_commands_remembers",
    "tests/pipeline/test_endpoint_bound.py::test_both_engines_say_it_on_the_same_records",
    "tests/export/test_audit_findings.py::test_a_command_flood_past_the_matchers_bound_is_in_the_export",
    "tests/transport/test_hostile_tcp.py::test_memory_does_not_grow_with_the_number_of_streams[syn-generations]",
    # one large real capture read again, a second engine of a live run
    "tests/analysis/test_story_real.py::test_parameter_sets_as_pymavlink_reads_them",
    "tests/live/test_live.py::test_pcap_flushed_while_running[pure-python]",
    "tests/live/test_live.py::test_sigterm_and_sigint_stop_cleanly[pure-python]",
    "tests/tui/test_app.py::test_key_dialog_shows_the_command_lines_error_for_a_bad_key",
    "tests/tui/test_app.py::test_key_dialog_tab_from_the_key_lands_on_add",
    "tests/native/test_stats_generated.py::test_story_is_identical",
    "tests/export/test_dask.py::test_dask_export_gives_the_local_rows",
)

# Parametrized tests (node id without the brackets) -> the parametrizations kept fast (fnmatch over the id);
# an entry here overrides the capture-sweep rule.
SWEEPS: dict[str, tuple[str, ...]] = {
    # tshark -T fields against ours: every -E form on the signed capture, the others on one form
    "tests/crosscheck/test_tshark_fields.py::test_integer_fields_as_tshark_prints_them":
        ("signed_udp.pcap-header=y quote=d", "px4_sitl_udp.pcap-occurrence=l aggregator=;"),
    "tests/crosscheck/test_tshark_fields.py::test_time_column_as_tshark_shows_it": ("dd",),
    # a capture from a pipe: a packet capture with damage and a raw stream (every kind in test-slow)
    "tests/capture/test_stdin.py::test_a_pipe_gives_the_files_frames": ("damaged.pcap", "serial_dump.raw"),
    # the mutants of a pcap with damage and of a raw stream (the framer's resynchronisation)
    "tests/pipeline/test_mutation_sweep.py::test_mutants_never_raise_and_stay_bounded":
        ("damaged.pcap", "serial_dump.raw"),
    # the signed capture with each key set, the damaged one without keys
    "tests/native/test_stats.py::test_bundled_capture": ("signed_udp.pcap-*", "damaged.pcap-no-keys-*"),
    "tests/security/test_no_secret_printed.py::test_every_command_keeps_the_keys_to_itself": ("signed_udp.pcap",),
    "tests/analysis/test_mission_real.py::test_after_the_last_empty_upload_the_vehicle_holds_no_mission":
        ("*ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog*",),
    # every dialect pymavlink ships, v1 and v2
    "tests/mavlink/test_dialect_input.py::test_every_dialect_pymavlink_ships_loads":
        ("v20/common.xml", "v10/minimal.xml"),
    # every hostile kind of dialect cache entry: one per way it is refused (a link, a byte, permissions, text)
    "tests/mavlink/test_dialect_cache.py::test_a_damaged_or_hostile_entry_is_ignored":
        ("symlink", "byte changed", "world writable", "not json"),
    # linear work at every chunk size of every pattern: every pattern at one size
    "tests/mavlink/test_hostile_framing.py::test_stream_work_is_linear": ("*-100",),
    "tests/mavlink/test_hidden_frames.py::test_the_walk_is_linear": ("*-100",),
    # every report with every hostile time: every report at one time, every time at one report
    "tests/capture/test_hostile_time.py::test_reports_print_any_time": ("*-EPB high word past 9999", "command0-*"),
    # every format, read window and cut of a shrinking capture: every format and cut at one window
    "tests/capture/test_hostile_shrink.py::test_a_capture_that_shrinks_while_read_ends_with_a_note": ("*-4096-*",),
    "tests/native/test_readers.py::test_the_read_window_changes_nothing": ("pcap", "tlog"),
    "tests/transport/test_tcp_holes.py::test_both_engines_agree_on_holes": ("jsonl",),
    # packets a Linux receiver drops: one of each layer (IP checksum, TCP placeholder, fragments, a tunnel)
    "tests/transport/test_checksum_review.py::test_an_insertion_a_linux_receiver_drops_is_left_out":
        ("ip-checksum-0", "tcp-placeholder", "fragments-wrong-header", "vxlan-outer-placeholder"),
}

# Modules that are nothing but a long sweep: none of their tests is fast (docs/testing.md, "Tiers").
WHOLLY_SLOW: frozenset[str] = frozenset()


def register_profiles() -> None:
    """`fast` (the default) and `full`, chosen by HYPOTHESIS_PROFILE. Both leave time out of it: no deadline
    and no too_slow health check, since a test never depends on how fast the machine is; they differ only in
    the examples a property test runs (`fast_examples`)."""
    common: dict[str, Any] = {"deadline": None, "suppress_health_check": [HealthCheck.too_slow]}
    settings.register_profile(FAST, **common)
    settings.register_profile(FULL, **common)
    settings.load_profile(os.environ.get(PROFILE_ENV, FAST))


def fast_examples(asked: int) -> int:
    """The examples a property test asking for `asked` runs in the fast tier."""
    return min(asked, max(EXAMPLES_FLOOR, asked // EXAMPLES_DIVISOR))


def cap_examples(test: Callable[..., Any]) -> None:
    """Run the hypothesis test `test` with `fast_examples` of its examples. Hypothesis has no public way to
    lower a count a test's own @settings gives (a profile only fills what @settings leaves out), so this
    replaces the settings @given keeps on the test, derived from them (tests/meta/test_tiers.py checks that
    it takes effect with the installed hypothesis); idempotent (a parametrized test is one function)."""
    function: Any = getattr(test, "__func__", test)
    full = getattr(function, "_mavscope_full_settings", None)
    if full is None:
        full = getattr(function, "_hypothesis_internal_use_settings", None)
        if not isinstance(full, settings):
            return
        function._mavscope_full_settings = full
    function._hypothesis_internal_use_settings = settings(full, max_examples=fast_examples(full.max_examples))


def _base(nodeid: str) -> tuple[str, str | None]:
    match = re.fullmatch(r"(.*?)\[(.*)\]", nodeid, flags=re.S)
    return (match.group(1), match.group(2)) if match else (nodeid, None)


def _capture_names() -> tuple[set[str], list[str]]:
    """The bundled captures' names, and the real ones' with REAL_KEPT's first (those on disk)."""
    def names(folder: Path) -> list[str]:
        return sorted(p.name for p in folder.iterdir() if p.suffix in _CAPTURE_SUFFIXES) if folder.is_dir() else []

    real = names(_REAL_CAPTURES)
    return set(names(_BUNDLED_CAPTURES)), [n for n in REAL_KEPT if n in real] + [n for n in real if n not in REAL_KEPT]


def _kept_of_sweep(members: list[tuple[str, str]], bundled: set[str], real: list[str]) -> list[str] | None:
    """The members a capture sweep keeps fast, or None when the members are no capture sweep."""
    named = {n: {c for c in bundled.union(real) if c in p} for n, p in members}
    captures = set().union(*named.values())
    if len(captures) < SWEEP_CAPTURES:
        return None
    real_kept = next((c for c in real if c in captures), None)
    kept_names = set(BUNDLED_KEPT) | ({real_kept} if real_kept else set())
    kept = [n for n, _ in members if not named[n] or named[n] & kept_names]
    return kept or [members[0][0]]


def slow_ids(nodeids: Sequence[str]) -> set[str]:
    """The node ids of `nodeids` the slow tier holds, by `SLOW`, `SWEEPS` and the capture-sweep rule."""
    slow = set()
    params: dict[str, list[tuple[str, str]]] = {}
    for nodeid in nodeids:
        base, param = _base(nodeid)
        if any(nodeid == p if "[" in p else fnmatchcase(base, p) for p in SLOW):
            slow.add(nodeid)
        if param is not None:
            params.setdefault(base, []).append((nodeid, param))
    bundled, real = _capture_names()
    for base, members in params.items():
        if base in SWEEPS:
            kept = [n for n, p in members if any(fnmatchcase(p, k) for k in SWEEPS[base])] or [members[0][0]]
        else:
            kept = _kept_of_sweep(members, bundled, real) or [n for n, _ in members]
        slow.update(n for n, _ in members if n not in kept)
    return slow


def mark(items: Iterable[pytest.Item]) -> None:
    items = list(items)
    slow = slow_ids([item.nodeid for item in items])
    cap = os.environ.get(PROFILE_ENV, FAST) == FAST
    for item in items:
        if item.nodeid in slow:
            item.add_marker(pytest.mark.slow)
        if cap and isinstance(item, pytest.Function) and is_hypothesis_test(item.obj):
            cap_examples(item.obj)
    report = os.environ.get(REPORT_ENV)
    if report:
        with open(report, "w", encoding="utf-8") as out:
            json.dump({item.nodeid: item.nodeid in slow for item in items}, out)
