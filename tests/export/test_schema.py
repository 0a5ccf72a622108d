"""The dataset's tables: typed message columns from the dialect (checked against pymavlink's own
generated classes), units and enum names in the metadata and as `_name` columns, char arrays and
invalid UTF-8, unknown messages (frames only, with their payload), MAVLink 1 extension fields, bounded
batches, and that the frames table has a column for every key of the JSON contract."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pyarrow as pa
import pytest
from pymavlink.dialects.v20 import all as v2

from mavscope.export import ExportOptions, record_batches, signed_batch, signed_schema, table_of
from mavscope.export.columns import FrameColumns
from mavscope.export.schema import FIXED_SCHEMAS, frames_schema
from tests.conftest import CAPTURES, ROOT, Cli
from tests.support.dataset import arrow_table, sha256
from tests.support.pmav import mav2
from tests.support.security import write_raw

# pymavlink's wire type -> the Arrow type a reader should see (written out here, not taken from mavscope)
ARROW = {"float": pa.float32(), "double": pa.float64(), "int8_t": pa.int8(), "uint8_t": pa.uint8(),
         "int16_t": pa.int16(), "uint16_t": pa.uint16(), "int32_t": pa.int32(), "uint32_t": pa.uint32(),
         "int64_t": pa.int64(), "uint64_t": pa.uint64()}


def _tables(path: Path, **kw: object) -> dict[str, pa.Table]:
    out: dict[str, list[pa.RecordBatch]] = {}
    for b in record_batches(path, ExportOptions(**kw)):  # type: ignore[arg-type]
        out.setdefault(table_of(b), []).append(b)
    return {k: pa.Table.from_batches(v) for k, v in out.items()}


@pytest.mark.parametrize("msg", ["HEARTBEAT", "GLOBAL_POSITION_INT", "BATTERY_STATUS", "STATUSTEXT", "SYS_STATUS"])
def test_message_columns_are_typed_as_pymavlink_declares_them(msg: str) -> None:
    t = _tables(CAPTURES / "px4_sitl_udp.pcap")[f"msg={msg}"]
    cls = getattr(v2, f"MAVLink_{msg.lower()}_message")
    names = [n for n in t.schema.names if not n.startswith("_") and n != "capture_id"]
    fields = [n for n in names if n in cls.fieldnames]
    assert fields == list(cls.fieldnames)  # XML order, every field
    for name, typ in zip(cls.fieldnames, cls.fieldtypes):
        col = t.schema.field(name)
        length = cls.array_lengths[cls.ordered_fieldnames.index(name)]
        base = typ.replace("_mavlink_version", "")
        if base == "char":
            assert col.type == pa.string()
        elif length:
            assert col.type == pa.list_(ARROW[base]), name
            assert {len(v) for v in t.column(name).to_pylist()} == {length}
        else:
            assert col.type == ARROW[base], name
        meta = col.metadata or {}
        assert meta.get(b"units", b"").decode() == (cls.fieldunits_by_name.get(name) or "").strip("[] ")
        assert meta.get(b"enum", b"").decode() == cls.fieldenums_by_name.get(name, "")
        if cls.fieldenums_by_name.get(name) and base != "char" and not length:
            assert t.schema.field(f"{name}_name").type == pa.string()


def test_enum_names_are_pymavlinks() -> None:
    t = _tables(CAPTURES / "px4_sitl_udp.pcap")["msg=HEARTBEAT"]
    for row in t.to_pylist():
        for field, enum in (("type", "MAV_TYPE"), ("autopilot", "MAV_AUTOPILOT"), ("system_status", "MAV_STATE")):
            assert row[f"{field}_name"] == v2.enums[enum][row[field]].name
        # MAV_MODE_FLAG is a bitmask: the names of the bits set, joined by "|"
        bits = [e.name for v, e in sorted(v2.enums["MAV_MODE_FLAG"].items())
                if v and row["base_mode"] & v == v and not e.name.endswith("_ENUM_END")]
        assert row["base_mode_name"] == "|".join(bits)


def test_strings_and_invalid_utf8(tmp_path: Path, cli: Cli) -> None:
    # STATUSTEXT text: plain ASCII, then bytes that are not UTF-8 (\xff, a cut 3-byte sequence)
    mav = mav2()
    frames = [mav.statustext_encode(6, t).pack(mav) for t in (b"hello", b"bad \xff byte", b"cut \xe2\x82")]
    path = write_raw(tmp_path, frames)
    texts = _tables(Path(path))["msg=STATUSTEXT"].column("text").to_pylist()
    # the JSON Lines rule (pymavlink's): the bytes up to the first NUL, undecodable bytes as \xNN escapes
    assert texts == ["hello", "bad \\xff byte", "cut \\xe2\\x82"]
    assert texts == [r["fields"]["text"] for r in cli.jsonl(path)]
    payloads = _tables(Path(path))["frames"].column("payload").to_pylist()
    assert b"bad \xff byte" in payloads[1]  # the bytes as sent stay in frames.payload


def test_unknown_messages_only_in_frames_with_their_payload() -> None:
    t = _tables(CAPTURES / "damaged.pcap")
    rows = t["frames"].to_pylist()
    unknown = [r for r in rows if r["msgid"] == 65000]
    assert len(unknown) == 1 and unknown[0]["msgname"] is None and unknown[0]["crc_status"] == "unchecked"
    assert len(unknown[0]["payload"]) == 10  # captures/README.md: a 10-byte payload
    assert not any("65000" in k for k in t)
    # decoded: bad-CRC frames (decoded, as read -T jsonl does); not decoded: truncated, unknown flags
    assert Counter(t["msg=ATTITUDE"].column("_crc_status").to_pylist()) == {"ok": 2, "bad": 1}
    # HEARTBEATs in records 1, 4, 7 (unknown incompat flag: not decoded), 8, 9 (truncated) (captures/README.md)
    assert t["msg=HEARTBEAT"].column("_frame").to_pylist() == [1, 4, 8]


def test_v1_extension_fields_are_null_v2_present() -> None:
    v1 = _tables(CAPTURES / "mavlink_v1_udp.pcap")["msg=SYS_STATUS"]
    assert set(v1.column("onboard_control_sensors_present_extended").to_pylist()) == {None}
    assert None not in v1.column("onboard_control_sensors_present").to_pylist()
    v2t = _tables(CAPTURES / "px4_sitl_udp.pcap")["msg=SYS_STATUS"]
    assert None not in v2t.column("onboard_control_sensors_present_extended").to_pylist()


def test_batches_are_bounded_and_rows_the_same() -> None:
    path = CAPTURES / "px4_sitl_udp.pcap"
    small = list(record_batches(path, ExportOptions(batch_rows=64)))
    assert max(b.num_rows for b in small) <= 64
    whole = _tables(path)
    for name, t in whole.items():
        if name == "captures":
            continue
        parts = [b for b in small if table_of(b) == name]
        assert repr(pa.Table.from_batches(parts).to_pylist()) == repr(t.to_pylist()), name  # repr: NaN == NaN


@pytest.mark.parametrize("source", ["python", "native"])
def test_frames_batches_hold_batch_rows_when_it_is_no_multiple_of_the_chunk(
        source: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The pure source turns frames into Arrow `CHUNK` at a time: with batch_rows 10 and chunks of 4, the
    frames batches still hold exactly 10 rows (the last one what is left), never 12."""
    monkeypatch.setattr(FrameColumns, "CHUNK", 4)
    path = CAPTURES / "px4_sitl_udp.pcap"
    sizes = [b.num_rows for b in record_batches(path, ExportOptions(batch_rows=10, source=source,
                                                                     tables=frozenset({"frames"})))]
    assert len(sizes) > 2 and set(sizes[:-1]) == {10} and 0 < sizes[-1] <= 10


def test_tables_option_and_schema_metadata() -> None:
    batches = list(record_batches(CAPTURES / "signed_udp.pcap", ExportOptions(tables=frozenset({"frames"}))))
    assert {table_of(b) for b in batches} == {"frames"}
    assert all(b.schema.equals(frames_schema(), check_metadata=True) for b in batches)
    assert batches[0].schema.metadata[b"mavscope.schema_version"] == b"1"
    assert set(batches[0].column("capture_id").to_pylist()) == {sha256(CAPTURES / "signed_udp.pcap")}


def test_frames_has_a_column_for_every_json_key() -> None:
    schema = json.loads((ROOT / "docs" / "frame.schema.json").read_text())
    props = schema["properties"]
    names = set(frames_schema().names)
    for key, spec in props.items():
        if key == "fields":
            continue  # the message tables
        if key in ("signature", "encryption"):
            inner = next(s for s in spec["oneOf"] if s.get("type") == "object")["properties"]
            assert {f"{key}_{k}" for k in inner} <= names, key
        else:
            assert key in names, key


def test_dataset_row_for_each_capture(tmp_path: Path, cli: Cli) -> None:
    root = tmp_path / "ds"
    assert cli("export", str(CAPTURES / "stats_loss.pcap"), "--parquet", str(root))[0] == 0
    row = arrow_table(root, "captures").to_pylist()[0]
    assert (row["name"], row["kind"], row["frame_count"], row["size"]) == (
        "stats_loss.pcap", "pcap", 495, (CAPTURES / "stats_loss.pcap").stat().st_size)
    findings = arrow_table(root, "findings").to_pylist()
    stats = cli.json("stats", str(CAPTURES / "stats_loss.pcap"))["findings"]
    assert sorted((f["code"], f["message"]) for f in findings if f["source"] == "stats") == sorted(
        (f["code"], f["message"]) for f in stats)


def test_every_column_is_documented() -> None:
    doc = (ROOT / "docs" / "dataset.md").read_text()
    for table, schema in FIXED_SCHEMAS.items():
        missing = [n for n in schema().names if f"`{n}`" not in doc]
        assert not missing, (table, missing)
    for name in ("_frame", "_index", "_time", "_sysid", "_compid", "_crc_status", "_signature_status"):
        assert f"`{name}`" in doc


def test_signed_types_for_spark_keep_every_value() -> None:
    t = _tables(CAPTURES / "signed_udp.pcap")
    for table in ("frames", "msg=HEARTBEAT", "msg=SYS_STATUS"):
        for batch in t[table].to_batches():
            signed = signed_batch(batch)
            assert not any(pa.types.is_unsigned_integer(f.type) or (pa.types.is_list(f.type) and
                           pa.types.is_unsigned_integer(f.type.value_type)) for f in signed.schema)
            assert signed.schema == signed_schema(batch.schema)
            assert signed.to_pylist() == batch.to_pylist()  # (no NaN in these tables)


@pytest.mark.parametrize("source", ["python", "native"])
def test_the_findings_are_computed_only_when_their_table_is_wanted(source: str) -> None:
    """`captures.finding_count` counts the findings table's rows; without that table the analyses do not run
    (the CSV export asks for the captures row only, for the problems): the count is null, not 0."""
    path = CAPTURES / "gcs_takeover.pcap"

    def captures(tables: frozenset[str] | None) -> dict[str, object]:
        batches = record_batches(path, ExportOptions(source=source, tables=tables))
        rows = [r for b in batches if table_of(b) == "captures" for r in b.to_pylist()]
        return rows[0]

    every = list(record_batches(path, ExportOptions(source=source)))
    found = sum(b.num_rows for b in every if table_of(b) == "findings")
    assert found and captures(None)["finding_count"] == found
    assert captures(frozenset({"captures"}))["finding_count"] is None
