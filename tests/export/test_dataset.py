"""The evidence for `mavscope export --parquet`: every bundled capture and every shared real capture
exported into one dataset, read back with DuckDB's and pyarrow's own readers, and checked against
`read -T jsonl` of the same capture: frames per link, per CRC, signature and encryption verdict and
per note code; rows per message type; and for the bundled captures every decoded value.

The expected side is computed from the JSON Lines with plain Python (tests/support/dataset.py); the
capture ids with hashlib. Extension fields of MAVLink 1 frames are the one documented difference:
null in the dataset (not on the wire), zero in the JSON (the payload is zero-padded before decoding);
which fields are extensions comes from pymavlink's v1.0 dialect, which has none.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink.dialects.v10 import all as v10

from tests.conftest import CAPTURES, Cli
from tests.support.dataset import (
    Counts,
    arrow_counts,
    arrow_table,
    duck_counts,
    expected_counts,
    jsonl,
    same,
    sha256,
)

BUNDLED = sorted(p for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))


@pytest.fixture(scope="module")
def bundled(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Counts, Counts]:
    root = tmp_path_factory.mktemp("bundled") / "dataset"
    status, out, err = Cli()("export", str(CAPTURES), "--parquet", str(root))
    assert status == 0, err
    assert out.startswith(f"exported {len(BUNDLED)} capture(s)"), out
    return root, duck_counts(root), arrow_counts(root)


def _check_counts(counts: tuple[Path, Counts, Counts], path: Path, rows: list[dict]) -> None:
    _, duck, arrow = counts
    want = expected_counts(rows)
    assert sum(want["link"].values()) == len(rows)
    for reader, got in (("duckdb", duck), ("pyarrow", arrow)):
        for key in ("msg", "link", "crc", "sig", "enc", "note"):
            assert got[sha256(path)][key] == want[key], (path.name, reader, key)


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_bundled_counts_per_message_link_and_verdict(cli: Cli, bundled: tuple[Path, Counts, Counts],
                                                     path: Path) -> None:
    _check_counts(bundled, path, jsonl(cli, path))


def test_real_captures_counts_per_message_link_and_verdict(cli: Cli, real_captures: Path, tmp_path: Path) -> None:
    files = sorted(p for p in real_captures.iterdir() if p.suffix != ".md")
    assert {p.name for p in files} >= {"ap_rover_mission_fence_rally_params.tlog", "ipal_transcriber_MAVLink.pcap"}
    root = tmp_path / "dataset"
    status, _, err = cli("export", str(real_captures), "--parquet", str(root))
    assert status == 0, err
    counts = (root, duck_counts(root), arrow_counts(root))
    captures = {r["capture_id"]: r for r in arrow_table(root, "captures").to_pylist()}
    assert sorted(captures) == sorted(sha256(p) for p in files)
    for path in files:
        rows = jsonl(cli, path)
        _check_counts(counts, path, rows)
        assert (captures[sha256(path)]["name"], captures[sha256(path)]["frame_count"]) == (path.name, len(rows))


def _v1_fields(msgname: str) -> set[str] | None:
    cls = getattr(v10, f"MAVLink_{msgname.lower()}_message", None)
    return None if cls is None else set(cls.fieldnames)


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_every_decoded_value_equals_the_json(cli: Cli, bundled: tuple[Path, Counts, Counts], path: Path) -> None:
    root = bundled[0]
    by_frame = {(r["frame"], r["index"]): r for r in jsonl(cli, path)}
    cid = sha256(path)
    checked = 0
    for d in sorted(root.glob("msg=*")):
        if not (d / f"capture_id={cid}").is_dir():
            continue
        for row in arrow_table(root, d.name, cid).to_pylist():
            want = by_frame[(row["_frame"], row["_index"])]
            assert want["msgname"] == d.name.removeprefix("msg=")
            assert (row["_sysid"], row["_compid"], row["_crc_status"]) == (want["sysid"], want["compid"],
                                                                          want["crc_status"])
            assert row["_signature_status"] == (want["signature"]["status"] if want["signature"] else None)
            v1 = _v1_fields(want["msgname"]) if want["version"] == 1 else None
            for name, value in want["fields"].items():
                if v1 is not None and name not in v1:
                    assert row[name] is None, (name, row[name])  # not on a MAVLink 1 wire
                else:
                    assert same(row[name], value), (path.name, want["frame"], name, row[name], value)
                checked += 1
    assert checked == sum(len(r["fields"]) for r in by_frame.values() if r["fields"] is not None)


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_frames_rows_equal_the_json_header_and_verdicts(cli: Cli, bundled: tuple[Path, Counts, Counts],
                                                        path: Path) -> None:
    rows = {(r["frame"], r["index"]): r for r in arrow_table(bundled[0], "frames", sha256(path)).to_pylist()}
    want = jsonl(cli, path)
    assert len(rows) == len(want)
    for w in want:
        r = rows[(w["frame"], w["index"])]
        for key in ("time", "transport", "src", "dst", "version", "len", "incompat_flags", "compat_flags", "seq",
                    "sysid", "compid", "msgid", "msgname", "crc", "crc_status"):
            assert r[key] == w[key], (path.name, w["frame"], key)
        sig = w["signature"] or {}
        for key in ("link_id", "timestamp", "value", "status", "key"):
            assert r[f"signature_{key}"] == sig.get(key), key
        if sig:  # ISO text in the JSON, a timestamp in Parquet
            assert r["signature_time"].strftime("%Y-%m-%dT%H:%M:%S.%f")[:-1] + "Z" == sig["time"]
        enc = w["encryption"] or {}
        for key in ("method", "scheme", "status", "reason"):
            assert r[f"encryption_{key}"] == enc.get(key), key
        assert r["notes"] == [n["code"] for n in w["notes"]]
        assert r["capture_path"] == str(path)
