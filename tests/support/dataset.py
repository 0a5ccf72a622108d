"""Reading an export dataset back without mavscope's code (DuckDB's and pyarrow's own readers), and the
counts the tests expect, computed from `read -T jsonl` (the JSON contract) with plain Python.

The capture id is computed here with hashlib, the Hive layout is read by DuckDB's `read_parquet` and
pyarrow's `dataset` with the partition column declared as text. Nothing here imports mavscope.export.
"""

from __future__ import annotations

import hashlib
import math
import struct
from collections import Counter
from pathlib import Path

import duckdb
import orjson
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as ds

from tests.conftest import Cli

HIVE = ds.partitioning(pa.schema([("capture_id", pa.string())]), flavor="hive")


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def expected_counts(rows: list[dict]) -> dict[str, Counter]:
    """Counts of one capture's JSON Lines: frames per message (decoded ones: a message table's rows), per
    link, per CRC, signature and encryption verdict, per note code."""
    out: dict[str, Counter] = {k: Counter() for k in ("msg", "link", "crc", "sig", "enc", "note")}
    for r in rows:
        if r["fields"] is not None:
            out["msg"][r["msgname"]] += 1
        out["link"][(r["sysid"], r["compid"])] += 1
        out["crc"][r["crc_status"]] += 1
        out["sig"][r["signature"]["status"] if r["signature"] else None] += 1
        out["enc"][r["encryption"]["status"] if r["encryption"] else None] += 1
        for n in r["notes"]:
            out["note"][n["code"]] += 1
    return out


def jsonl(cli: Cli, path: Path, *args: str) -> list[dict]:
    """`read PATH ARGS -T jsonl`, parsed (orjson: the real captures have 230,000 lines)."""
    status, out, err = cli("read", str(path), *args, "-T", "jsonl")
    assert status == 0, err
    return [orjson.loads(line) for line in out.splitlines()]


def parquet(root: Path, table: str) -> str:
    return str(root / table / "capture_id=*" / "*.parquet").replace("'", "''")


Counts = dict[str, dict[str, Counter]]  # capture id -> kind of count -> Counter


def _empty() -> dict[str, Counter]:
    return {k: Counter() for k in ("msg", "link", "crc", "sig", "enc", "note")}


def duck_counts(root: Path) -> Counts:
    """The same counts per capture, from the dataset, with DuckDB's own Parquet reader."""
    con = duckdb.connect()
    out: Counts = {}

    def src(table: str) -> str:
        return (f"read_parquet('{parquet(root, table)}', hive_partitioning = true, "
                "hive_types = {'capture_id': VARCHAR})")

    def count(kind: str, sql: str) -> None:
        for cid, *key, n in con.execute(sql).fetchall():
            out.setdefault(cid, _empty())[kind][tuple(key) if len(key) > 1 else key[0]] = n

    frames = src("frames")
    count("link", f"SELECT capture_id, sysid, compid, count(*) FROM {frames} GROUP BY ALL")
    count("crc", f"SELECT capture_id, crc_status, count(*) FROM {frames} GROUP BY ALL")
    count("sig", f"SELECT capture_id, signature_status, count(*) FROM {frames} GROUP BY ALL")
    count("enc", f"SELECT capture_id, encryption_status, count(*) FROM {frames} GROUP BY ALL")
    count("note", f"SELECT capture_id, code, count(*) FROM (SELECT capture_id, unnest(notes) AS code FROM {frames}) "
                  "GROUP BY ALL")
    for d in sorted(root.glob("msg=*")):
        name = d.name.removeprefix("msg=").replace("'", "")
        count("msg", f"SELECT capture_id, '{name}', count(*) FROM {src(d.name)} GROUP BY ALL")
    con.close()
    return out


def arrow_table(root: Path, table: str, capture_id: str | None = None, columns: list[str] | None = None) -> pa.Table:
    """A table of the dataset with pyarrow's dataset reader (one capture's rows with `capture_id`)."""
    d = ds.dataset(root / table, format="parquet", partitioning=HIVE)
    flt = None if capture_id is None else ds.field("capture_id") == capture_id
    return d.to_table(filter=flt, columns=columns)


def arrow_counts(root: Path) -> Counts:
    """The same counts per capture, with pyarrow's dataset reader and its group-by."""
    out: Counts = {}

    def count(kind: str, t: pa.Table, keys: list[str]) -> None:
        for r in t.group_by(["capture_id", *keys]).aggregate([([], "count_all")]).to_pylist():
            key = tuple(r[k] for k in keys)
            out.setdefault(r["capture_id"], _empty())[kind][key if len(key) > 1 else key[0]] = r["count_all"]

    cols = ["capture_id", "sysid", "compid", "crc_status", "signature_status", "encryption_status", "notes"]
    frames = arrow_table(root, "frames", columns=cols)
    count("link", frames, ["sysid", "compid"])
    count("crc", frames, ["crc_status"])
    count("sig", frames, ["signature_status"])
    count("enc", frames, ["encryption_status"])
    notes = frames.column("notes").combine_chunks()
    ids = pc.take(frames.column("capture_id"), pc.list_parent_indices(notes))
    count("note", pa.table({"capture_id": ids, "code": pc.list_flatten(notes)}), ["code"])
    for d in sorted(root.glob("msg=*")):
        t = arrow_table(root, d.name, columns=["capture_id"])
        count("msg", t.append_column("msg", pa.array([d.name.removeprefix("msg=")] * t.num_rows)), ["msg"])
    return out


def same(a: object, b: object) -> bool:
    """Values equal, a NaN in Parquet being the JSON's null (JSON cannot carry NaN), and a float32 column's
    value (a float32 widened to a double) the JSON's shortest decimal of that float32 (docs/json-format.md)."""
    if isinstance(a, float) and math.isnan(a):
        return b is None
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float) and a != b and abs(a) < 3.4e38 and abs(b) < 3.4e38:
        f32 = struct.Struct("<f")
        return f32.unpack(f32.pack(a))[0] == a and f32.pack(a) == f32.pack(b)
    return a == b
