"""mavscope on every bundled capture against the truth the generator recorded (captures/expected.json).

The generator knows what it wrote (frames, their records, offsets, CRC verdicts, truncations, skipped
bytes) without decoding anything: this is the known truth the dissection engine must reproduce.
"""

from __future__ import annotations

import io
import json
import re

import jsonschema
import pytest

from mavscope.cli import Env, main
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus
from tests.conftest import CAPTURES, ROOT
from tests.crosscheck.test_pymavlink import dissect

EXPECTED = json.loads((CAPTURES / "expected.json").read_text()) if (CAPTURES / "expected.json").exists() else {}
SCHEMA = json.loads((ROOT / "docs" / "frame.schema.json").read_text())


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_frames_match_the_generators_truth(name: str, dialect: Dialect) -> None:
    exp = EXPECTED[name]
    frames, anomalies = dissect(CAPTURES / name, dialect)
    whole = [f for f in frames if f.crc_status is not CrcStatus.TRUNCATED]
    cut = [f for f in frames if f.crc_status is CrcStatus.TRUNCATED]
    assert len(whole) == exp["frames"]
    assert sum(f.crc_status is CrcStatus.OK for f in whole) == exp["crc_ok"]
    assert sum(f.crc_status is CrcStatus.BAD for f in whole) == exp["crc_bad"]
    assert sum(f.crc_status is CrcStatus.UNCHECKED for f in whole) == exp["crc_unchecked"]
    assert sum(f.version == 1 for f in whole) == exp["v1"]
    assert sum(f.signature is not None for f in whole) == exp["signed"]
    assert len(cut) == exp["truncated"]
    ours = [[f.record if exp["records"] is not None and name != "serial_dump.raw" else None,
             f.index - 1, f.sysid, f.compid, f.seq, f.msgid] for f in whole]
    theirs = exp["frame_list"]
    if name == "serial_dump.raw":
        ours = [o[2:] for o in ours]
        theirs = [t[2:] for t in theirs]
    else:
        # The generator numbers frames per record from 0 among those whose first byte is in it; for
        # TCP the order within the capture can differ (frames complete later): compare sorted.
        ours = sorted(o[2:] + [o[0]] for o in ours)
        theirs = sorted(t[2:] + [t[0]] for t in theirs)
    assert ours == theirs
    assert sorted(f.offset for f in whole) == sorted(exp["frame_offsets"])
    assert [f.crc_status.value for f in sorted(whole, key=lambda f: f.offset)] == [
        c for _, c in sorted(zip(exp["frame_offsets"], exp["frame_crc"]))
    ]
    assert sorted(f.offset for f in cut) == sorted(off for _, off in exp["truncated_list"])
    skipped = sum(int(re.match(r"(\d+) bytes", n.message).group(1))  # type: ignore[union-attr]
                  for item in [*frames, *anomalies] for n in item.notes if n.code == "skipped-bytes")
    assert skipped == exp["skipped_bytes"]


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_jsonl_output_validates_against_the_schema(name: str) -> None:
    out, err = io.StringIO(), io.StringIO()
    assert main(["read", str(CAPTURES / name), "-T", "jsonl"], Env(stdout=out, stderr=err)) == 0
    validator = jsonschema.Draft202012Validator(SCHEMA)
    lines = out.getvalue().splitlines()
    assert lines
    for line in lines:
        validator.validate(json.loads(line))
