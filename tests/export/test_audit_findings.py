"""The export's findings table (source `audit`) holds `mavscope audit`'s findings, whatever the order of the
frames, with both batch sources (native and MAVSCOPE_PURE=1) giving the same rows.

One implementation serves both (mavscope.analysis.audit_pass): the audit's verdict summary, the unsigned and
v1 frames of signing senders judged with the whole capture (issue 35 item 4), the command matcher's
give-ups and the expert's security findings. The native source feeds the deferred judgement in bulk
(native_findings.NativeFeed._downgrades) and the command matcher only where it could give up; these tests
hold both to the pure pass and to the expectations below, derived from the signing specification.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import all as v2

from mavscope.native import export as native
from mavscope.pipeline.options import PipelineOptions
from mavscope.security import downgrade
from tests.conftest import CAPTURES, Cli
from tests.export.test_native_findings import native_analyses, pure_analyses
from tests.native.engines import PURE
from tests.security.test_signing_order import KEY, captures
from tests.support.dataset import arrow_table
from tests.support.pmav import heartbeat as heartbeat_v1
from tests.support.pmav import mav1
from tests.support.security import SHA_KEY, command_long, heartbeat, radio_status, signer, write_raw

ENGINES = {"native": {}, "pure": PURE}

pytestmark = pytest.mark.skipif(native._native is None, reason="the native extension is not built")


def rows(findings: list[dict]) -> list[tuple[str, str, str, tuple[int, ...]]]:
    return sorted((f["code"], f["severity"], f["message"], tuple(f["frames"])) for f in findings)


def exported(cli: Cli, tmp_path: Path, path: str, keys: list[str], environ: dict[str, str]) -> list[dict]:
    """The findings table's rows of source `audit` after `export PATH --parquet`."""
    root = tmp_path / f"ds-{len(list(tmp_path.iterdir()))}"
    status, _, err = cli("export", path, *keys, "--parquet", str(root), environ=environ)
    assert status == 0, err
    if not (root / "findings").exists():  # a capture without findings (the export writes no empty table)
        return []
    return [r for r in arrow_table(root, "findings").to_pylist() if r["source"] == "audit"]


@pytest.mark.parametrize("keys", [KEY, []], ids=["key", "no-key"])
def test_the_export_holds_audits_findings_in_either_order(cli: Cli, tmp_path: Path, keys: list[str]) -> None:
    # tests/security/test_signing_order.py's captures: 255/190 signs three HEARTBEATs; an unsigned COMMAND_LONG
    # and a MAVLink v1 HEARTBEAT claim 255/190, "before" them (frames 1, 2) or "after" them (frames 4, 5).
    # MAVLink's signing specification: a receiver with signing set up rejects unsigned frames (but
    # RADIO_STATUS) of any place, so each order has one unsigned-in-signed-stream (the COMMAND_LONG's frame)
    # and one v1-in-signed-stream (the v1 HEARTBEAT's); frame numbers count the frames in the order written.
    want = {"before": ([1], [2]), "after": ([4], [5])}
    for order, path in captures(tmp_path).items():
        tables = {}
        for engine, environ in ENGINES.items():
            status, out, err = cli("audit", path, "--json", *keys, environ=environ)
            assert status == 1, err
            audit = json.loads(out)["findings"]
            by_code = {f["code"]: f["frames"] for f in audit}
            assert (by_code["unsigned-in-signed-stream"], by_code["v1-in-signed-stream"]) == want[order], engine
            tables[engine] = exported(cli, tmp_path, path, keys, environ)
            assert rows(tables[engine]) == rows(audit), (order, engine)
        assert rows(tables["native"]) == rows(tables["pure"]), order


def senders_capture(tmp_path: Path) -> str:
    """Four senders around signing, in windows of 3 frames and more: 1/1 sends unsigned v2 and v1 frames (and an
    unsigned RADIO_STATUS) then signs, then an unsigned one; 2/1 unsigned frames, signing in the middle of
    them; 3/1 signs with its last frame; 4/1 signs first (its unsigned frame the stage notes as it comes)."""
    a, b, c, d = (signer(SHA_KEY, s, 1) for s in (1, 2, 3, 4))
    ua, ub, uc, ud = (signer(None, s, 1) for s in (1, 2, 3, 4))
    frames = [heartbeat(d), command_long(ua), command_long(ub), heartbeat_v1(mav1(1, 1)), command_long(uc),
              radio_status(ua), command_long(ua, 21), heartbeat(ub), command_long(ub, 22), heartbeat(b),
              command_long(ub, 23), command_long(ua, 24), heartbeat_v1(mav1(1, 1)), command_long(uc, 25),
              command_long(ud), heartbeat(a), command_long(ua, 26), heartbeat(uc), heartbeat(c), heartbeat(ud)]
    return write_raw(tmp_path, frames, "senders.raw")


def downgrades_state(a: object) -> dict[str, object]:
    d = a.audit_pass.downgrades  # type: ignore[attr-defined]
    return {"signers": sorted(d.signers), "listed": d.listed,
            "early": [(s, e.v1, e.v2, e.listed) for s, e in d.early.items()]}


@pytest.mark.parametrize("window", [65_536, 3, 1])
@pytest.mark.parametrize("caps", [(1000, 100_000), (2, 4), (1, 2)], ids=["default", "2-4", "1-2"])
def test_the_bulk_feed_judges_as_each_frame_does(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, window: int,
                                                  caps: tuple[int, int]) -> None:
    # Downgrades.add frame by frame (the pure pass) is the reference; the native feed counts and lists in
    # bulk, the caps (per sender, over all) taken in capture order as `add` takes them
    monkeypatch.setattr(native, "WINDOW_FRAMES", window)
    monkeypatch.setattr(downgrade, "EARLY_LISTED", caps[0])
    monkeypatch.setattr(downgrade, "EARLY_TOTAL", caps[1])
    path = senders_capture(tmp_path)
    for pipeline in (PipelineOptions(), PipelineOptions(keys=(KEY[1],))):
        want, got = (downgrades_state(f(path, pipeline)) for f in (pure_analyses, native_analyses))
        assert got == want
        # by hand, frame by frame (senders_capture): 1/1 sends 3 unsigned v2 frames (and a RADIO_STATUS, which
        # a signing receiver takes) and 2 v1 frames before its first signed one, 2/1 3 unsigned, 3/1 3
        # unsigned; 4/1's unsigned frame comes after its signed one (the stage's)
        assert want["signers"] == [(1, 1), (2, 1), (3, 1), (4, 1)]
        early = {s: (v1, v2) for s, v1, v2, _ in want["early"]}  # type: ignore[attr-defined]
        assert early == {(1, 1): (2, 3), (2, 1): (0, 3), (3, 1): (0, 3)}


def test_a_command_flood_past_the_matchers_bound_is_in_the_export(cli: Cli, tmp_path: Path) -> None:
    # 4,100 COMMAND_LONGs of distinct command ids from 255/190, none answered: the command matcher holds at
    # most PENDING_MAX (4,096) waiting, so it gives up 4 of them, a capacity finding audit reports
    # (analysis/command_log.py); the native source, which does not feed the matcher while the capture has
    # sent no more distinct commands than that, runs it over a pure pass here
    from mavscope.analysis.command_log import PENDING_MAX

    mav = v2.MAVLink(None, srcSystem=255, srcComponent=190)
    frames = [bytes(mav.command_long_encode(1, 1, k, 0, 0, 0, 0, 0, 0, 0, 0).pack(mav)) for k in range(PENDING_MAX + 4)]
    path = write_raw(tmp_path, frames, "flood.raw")
    tables = {}
    for engine, environ in ENGINES.items():
        audit = json.loads(cli("audit", path, "--json", environ=environ).out)["findings"]
        (capacity,) = [f for f in audit if f["code"] == "capacity" and "ACK" in f["message"]]
        assert ": 4 given up (4 commands)" in capacity["message"], capacity  # 4,100 waiting, 4,096 held
        tables[engine] = exported(cli, tmp_path, path, [], environ)
        assert rows(tables[engine]) == rows(audit), engine
    assert rows(tables["native"]) == rows(tables["pure"])


BUNDLED = sorted(p for p in CAPTURES.iterdir() if p.suffix not in (".md", ".json"))
DEMO_KEY = ["--key", "passphrase:mavscope-demo"]  # the generator signs the GCS's frames with it (captures/README.md)


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_the_export_holds_audits_findings_on_the_bundled_captures(cli: Cli, tmp_path: Path, path: Path) -> None:
    # the expert's wording of a code both report (key-leak on commands_ack.pcap), the deferred verdicts
    # (key_exchange_udp.pcap's unsigned frames before the first signed ones), the command matcher's
    for keys in ([], DEMO_KEY) if path.name in SIGNED else ([],):
        tables = {}
        for engine, environ in ENGINES.items():
            r = cli("audit", str(path), "--json", *keys, environ=environ)
            assert r.status in (0, 1), r.err
            tables[engine] = exported(cli, tmp_path, str(path), keys, environ)
            assert rows(tables[engine]) == rows(json.loads(r.out)["findings"]), (engine, keys)
        assert rows(tables["native"]) == rows(tables["pure"]), keys


SIGNED = {"signed_udp.pcap", "key_exchange_udp.pcap", "commands_ack.pcap", "gcs_takeover.pcap"}
