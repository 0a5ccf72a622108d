"""The TUI's verdict marks read without colour (issue 35 item 15): in each column of the CSE verdicts the
glyphs differ, one cell each, and the packet list of a capture with every signature verdict shows them
apart. Expected marks: the table below, by hand (docs/tui.md), and the verdicts of tests/support/verdicts.py
(from how its frames were built)."""

from __future__ import annotations

from pathlib import Path

from rich.cells import cell_len

from mavscope.mavlink.frame import CrcStatus, EncryptionStatus, SignatureStatus
from mavscope.pipeline.options import PipelineOptions
from mavscope.tui.app import create_app
from mavscope.tui.sessions import TuiOptions
from mavscope.tui.verdicts import CRC_GLYPHS, ENCRYPTION_GLYPHS, SIGNATURE_GLYPHS
from mavscope.tui.widgets.packet_list import COLUMNS
from tests.support.tui import ready, run
from tests.support.verdicts import KEY_OPTION, VERDICTS, write_signed

MARKS = {
    "crc": {CrcStatus.OK: "✓", CrcStatus.BAD: "✗", CrcStatus.UNCHECKED: "?", CrcStatus.TRUNCATED: "…"},
    "signature": {"valid": "S", "invalid": "X", "replay": "R", "no-key": "s", "truncated": "…", "unsigned": "U",
                  "v1": "1"},
    "encryption": {"decrypted": "D", "no-key": "E", "failed": "X"},
}


def test_each_column_has_a_glyph_per_verdict() -> None:
    for column, table in (("crc", CRC_GLYPHS), ("signature", SIGNATURE_GLYPHS), ("encryption", ENCRYPTION_GLYPHS)):
        glyphs = {k: v[0] for k, v in table.items()}
        assert glyphs == MARKS[column]
        assert len(set(glyphs.values())) == len(glyphs), column  # no two verdicts of a column alike
        assert all(cell_len(g) == 1 for g in glyphs.values())
    assert set(SIGNATURE_GLYPHS) >= {s.value for s in SignatureStatus}
    assert set(ENCRYPTION_GLYPHS) == {s.value for s in EncryptionStatus}


def test_packet_list_shows_each_signature_verdict_apart(tmp_path: Path) -> None:
    path = write_signed(tmp_path)
    at = sum(w for _, w in COLUMNS[:6])  # the CSE column follows the Message column

    async def scenario(options: TuiOptions, want: dict[int, str]) -> None:
        app = create_app(path, options)
        async with app.run_test(size=(160, 30)) as pilot:
            await ready(pilot)
            lines = {}
            for y in range(1, len(app.index) + 1):
                text = app.packet_list.render_line(y).text
                lines[int(text.split()[0])] = text[at : at + 3]
            assert {n: cse[1] for n, cse in lines.items()} == want, lines
            assert lines[6][0] == "…"  # the cut frame's CRC is missing too

    run(scenario(TuiOptions(pipeline=PipelineOptions(keys=(KEY_OPTION[1],))),
                 {n: MARKS["signature"][v] for n, v in VERDICTS.items()}))
    run(scenario(TuiOptions(), {n: ("…" if n == 6 else "s") for n in VERDICTS}))
