"""The column mode's note codes: frames with notes the native walker takes as ordinary traffic.

With `Columns(notes=True)` (what `stats` and every analysis over FrameBatches read: native.windows) the
walker takes an unsigned or MAVLink 1 frame of a sender seen signing, and a bad-CRC frame the framer shows
as a frame, as rows with a code (columns.h MS_NOTE_*), instead of handing their records back; Python makes
their Frames (`windows.noted`) from the framer's and the security stage's own note makers. The reference
is the Python pipeline (`MAVSCOPE_PURE=1`): every row's columns and its whole Frame (notes, verdict, CRC
status) must be its; which rows carry which code is written out by hand from the rules (security/stage.py,
framing.py), and no record of these captures may be handed back.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mavscope.mavlink.dialect import load_dialect
from mavscope.pipeline.batch import FrameBatch
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import open_session
from tests.conftest import Cli
from tests.native.test_bad_crc_native import _attitude, _bad
from tests.native.test_unsigned_notes import GCS, VEHICLE
from tests.native.test_unsigned_notes import _capture as unsigned_capture
from tests.support.flows import write_udp_pcap
from tests.support.security import SHA_KEY, heartbeat, signer


@pytest.fixture(autouse=True)
def _built() -> None:
    from mavscope.native.core import available

    if not available({}):
        pytest.skip("the C extension is not built")


def _mixed(tmp: Path) -> tuple[Path, list[int]]:
    """1/1 signs, then sends unsigned frames, bad-CRC frames (unsigned: with both notes) and a bad-CRC frame
    of 2/1 (which never signs): the expected code of each frame, by hand (1 unsigned, 4 bad CRC)."""
    s, v, other = signer(SHA_KEY, 1, 1), signer(None, 1, 1), signer(None, 2, 1)
    datagrams = [heartbeat(s), _attitude(v), _bad(_attitude(v, 0.3)), _bad(_attitude(other, 0.4)),
                 heartbeat(s) + _attitude(v, 0.5), _attitude(other)]
    codes = [0, 1, 4 | 1, 4, 0, 1, 0]
    return write_udp_pcap(tmp / "mixed.pcap", [(VEHICLE, GCS, d) for d in datagrams]), codes


def _batches(path: Path, environ: dict[str, str]) -> tuple[list[FrameBatch], dict[str, int]]:
    with open_session(str(path), PipelineOptions(), environ=environ) as s:
        got = list(s.batches(lambda _item: None))
        return got, dict(s.walked)


def _frames(batches: list[FrameBatch]) -> list[object]:
    return [f for b in batches for f in b.frames(list(range(b.n)))]


def _joined(batches: list[FrameBatch], name: str) -> list[object]:
    return np.concatenate([getattr(b, name) for b in batches]).tolist() if batches else []


@pytest.mark.parametrize("which", ["unsigned", "mixed"])
def test_noted_rows_are_the_python_pipelines_frames(which: str, tmp_path: Path) -> None:
    if which == "unsigned":
        path, expected = unsigned_capture(tmp_path)
        # by hand from test_unsigned_notes' list: frames 3 (MAVLink 2) and 7.2 unsigned, 4 MAVLink 1
        codes = [0, 0, 1, 2, 0, 0, 0, 1]
    else:
        path, codes = _mixed(tmp_path)
    native, walked = _batches(path, {})
    pure, _ = _batches(path, {"MAVSCOPE_PURE": "1"})
    assert walked["records_handed_back"] == 0  # ordinary traffic: taken whole
    assert _joined(native, "coded") == codes
    for name in ("record", "time", "timed", "transport", "version", "seq", "sysid", "compid", "msgid", "size", "crc",
                 "verdict", "signed", "clean"):
        assert _joined(native, name) == _joined(pure, name), name
    frames = _frames(native)
    assert frames == _frames(pure)
    assert [n.code for f in frames for n in f.notes].count("bad-crc") == sum(1 for c in codes if c & 4)


def test_stats_and_findings_alike_on_both_engines(cli: Cli, tmp_path: Path) -> None:
    path, _ = _mixed(tmp_path)
    for extra in (("--json",), ()):
        assert cli("stats", str(path), *extra, environ={}) == cli("stats", str(path), *extra,
                                                                   environ={"MAVSCOPE_PURE": "1"})


def test_a_detector_that_reads_no_note_gets_no_noted_row_of_another_message(tmp_path: Path) -> None:
    """expert_batch: of the coded rows, a detector with `notes` gets its messages' and those with a note it
    reads; BadCrcBursts (notes {"bad-crc"}) gets both bad-CRC ATTITUDEs, GnssAnomalies (none) none of them."""
    from mavscope.analysis import expert_batch
    from mavscope.analysis.expert import BadCrcBursts, Expert
    from mavscope.analysis.gnss import GnssAnomalies

    path, _ = _mixed(tmp_path)
    seen: dict[str, list[int]] = {"bad": [], "gnss": []}

    class Bad(BadCrcBursts):
        def add(self, f, fields):  # type: ignore[no-untyped-def]
            seen["bad"].append(f.record)
            super().add(f, fields)

    class Gnss(GnssAnomalies):
        def add(self, f, fields):  # type: ignore[no-untyped-def]
            seen["gnss"].append(f.record)
            super().add(f, fields)

    dialect = load_dialect()
    expert = Expert(dialect, [Bad, lambda: Gnss(dialect)])
    native, _ = _batches(path, {})
    for b in native:
        expert_batch.feed(expert, b)
    assert seen == {"bad": [3, 4], "gnss": []}


def test_a_datagram_of_bad_frames_to_a_mavlink_port_is_taken(tmp_path: Path) -> None:
    """A first datagram from an unknown source whose every frame has a bad CRC, sent to MAVLink's port
    14550: the framer shows it as a frame (dissect.py: a MAVLink port is reason to expect MAVLink), so the
    column walk takes it with its code as the JSON walk does (test_bad_crc_native), not handed back."""
    v = signer(None, 3, 1)
    path = write_udp_pcap(tmp_path / "port.pcap", [(("10.0.0.9", 40000), ("10.0.0.1", 14550), _bad(_attitude(v)))])
    native, walked = _batches(path, {})
    pure, _ = _batches(path, {"MAVSCOPE_PURE": "1"})
    assert walked["records_handed_back"] == 0
    assert _joined(native, "coded") == [4]
    assert _frames(native) == _frames(pure)
