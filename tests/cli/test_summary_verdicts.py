"""`read --key` summary lines say a signature's verdict when it is not valid (issue 35 item 15): the Info
ends with `[signed link N, signature replay]`, `[signed link N, signature invalid]`, or, for a signature
cut short, `[signature truncated]`; a valid signature, or any signature without a key, is `[signed link N]`
alone. Both engines write the same lines (the native writer hands the frames it does not judge valid back).
Expected verdicts: tests/support/verdicts.py, from how the frames were built."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import Cli
from tests.native.engines import same
from tests.support.verdicts import KEY_OPTION, VERDICTS, write_signed

SAID = {"valid": "[signed link 1]", "replay": "[signed link 1, signature replay]",
        "invalid": "[signed link 1, signature invalid]", "truncated": "[signature truncated]"}


def _ends(out: str) -> dict[int, str]:
    lines = out.splitlines()
    return {int(line.split()[0]): line for line in lines}


@pytest.mark.parametrize("engine", [{"MAVSCOPE_PURE": "1"}, {}], ids=["pure", "native"])
def test_summary_lines_say_the_verdicts(engine: dict[str, str], tmp_path: Path) -> None:
    path = write_signed(tmp_path)
    status, out, err = Cli(engine)("read", str(path), *KEY_OPTION)
    assert status == 0, err
    lines = _ends(out)
    assert sorted(lines) == sorted(VERDICTS)
    for n, verdict in VERDICTS.items():
        assert lines[n].endswith(SAID[verdict]), (n, lines[n])
    status, out, err = Cli(engine)("read", str(path))  # no key: the signatures unjudged (no-key), but the
    assert status == 0, err  # one cut short, which needs no key to tell
    lines = _ends(out)
    assert all(lines[n].endswith("[signed link 1]") for n in range(1, 6))
    assert lines[6].endswith("[signature truncated]") and out.count("signature") == 1


def test_both_engines_say_them_alike(cli: Cli, tmp_path: Path) -> None:
    pytest.importorskip("mavscope._native", reason="the native extension is not built")
    path = write_signed(tmp_path)
    for keys in ((), KEY_OPTION):
        same(cli, path, *keys, fmt=())
        same(cli, path, *keys, "-c", "3", fmt=())
