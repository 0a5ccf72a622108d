"""The engine is chosen in one place: `open_session` (Session.engine), from mavscope.native.core's rule.

A front end (a command, the TUI, the export) never asks mavscope.native.core whether the native engine runs:
it opens its capture with `open_session` (through `capture_session` for the commands) and asks the session.
The exceptions are written out here, each with its reason: `--version` names the engine of the process;
`live` reads no capture file (its sources are sockets: the native receiver and walker are chosen where
the source is made); the export's `--source auto` names a batch source by the same rule. The test reads
every module's source (AST) for a call of `engine(...)` or `available(...)` imported from
mavscope.native.core, and checks by hand-written cases that Session.engine follows MAVSCOPE_PURE.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import open_session
from tests.conftest import CAPTURES

PACKAGE = Path(__file__).resolve().parents[2] / "mavscope"
FRONT_ENDS = ("commands", "tui", "export", "browse", "output", "cli.py", "__main__.py")
ALLOWED = {
    "cli.py": "--version names the process's engine",
    "commands/live.py": "a live source reads sockets, not a capture file (no session)",
    "export/source.py": "--source auto names the batch source by core's rule",
}


def _engine_calls(path: Path) -> list[int]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module == "mavscope.native.core":
            names |= {a.asname or a.name for a in node.names if a.name in ("engine", "available")}
    return [node.lineno for node in ast.walk(tree)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in names]


def test_front_ends_ask_the_session() -> None:
    found = {}
    for part in FRONT_ENDS:
        root = PACKAGE / part
        for path in ([root] if root.suffix == ".py" else sorted(root.rglob("*.py"))):
            rel = path.relative_to(PACKAGE).as_posix()
            lines = _engine_calls(path)
            if lines and rel not in ALLOWED:
                found[rel] = lines
    assert found == {}, f"the engine chosen outside open_session: {found}"
    for rel in ALLOWED:  # each exception still exists (else it is stale here)
        assert _engine_calls(PACKAGE / rel), rel


@pytest.mark.parametrize(("environ", "want"), [({"MAVSCOPE_PURE": "1"}, "pure-python"),
                                               ({"MAVSCOPE_PURE": "0"}, "native"), ({}, "native")])
def test_the_session_chooses_by_mavscope_pure(environ: dict[str, str], want: str) -> None:
    from mavscope.native.core import _native

    if _native is None and want == "native":
        pytest.skip("the C extension is not built")
    with open_session(str(CAPTURES / "signed_udp.pcap"), PipelineOptions(), environ=environ) as s:
        assert s.engine == want
