"""The Python/C contract has one definition on each side: the C extension's names are typed once, in
mavscope/_native.pyi, and the constants Python shares with C (capture kinds, transport codes, the engine
switch MAVSCOPE_PURE) are defined once, in mavscope/native/core.py, which is also the only module that imports
the extension. These tests fail on a second copy, whatever its module.

The expected names of the second test come from the built module itself (dir()), never from the stub.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from tests.conftest import ROOT

PACKAGE = ROOT / "mavscope"
CORE = PACKAGE / "native" / "core.py"
STUB = PACKAGE / "_native.pyi"
KIND_NAMES = {"pcap", "pcapng", "tlog", "raw"}
TRANSPORT_NAMES = {"udp", "tcp", "tlog", "raw"}
# a numbering copied from the C headers cites the header's enum (capture.h, columns.h)
HEADER_ENUMS = re.compile(r"\bMS_(KIND|TRANSPORT|TR)_")


def _docstrings(tree: ast.AST) -> set[int]:
    """The ids of the docstring nodes of `tree` (prose may name MAVSCOPE_PURE)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def _copies(path: Path, root: Path = ROOT) -> list[str]:
    """What in `path` is a second definition of the contract's constants, or a second import of the
    extension (places shown relative to `root`), in the order of their lines."""
    text = path.read_text(encoding="utf-8")
    tree = ast.parse(text)
    docs = _docstrings(tree)
    found = []
    for node in ast.walk(tree):
        where = f"{path.relative_to(root)}:{getattr(node, 'lineno', 0)}"
        if isinstance(node, ast.Constant) and node.value == "MAVSCOPE_PURE" and id(node) not in docs:
            found.append(f"{where}: the string MAVSCOPE_PURE (use mavscope.native.core.PURE_ENV / available())")
        elif isinstance(node, ast.Dict):
            pairs = [(k.value, v.value) for k, v in zip(node.keys, node.values)
                     if isinstance(k, ast.Constant) and isinstance(v, ast.Constant)]
            if any(k in KIND_NAMES and type(v) is int for k, v in pairs):
                found.append(f"{where}: capture kinds numbered (use mavscope.native.core.KINDS)")
            if any(type(k) is int and v in TRANSPORT_NAMES for k, v in pairs):
                found.append(f"{where}: transports numbered (use mavscope.native.core's *_TRANSPORTS)")
        elif isinstance(node, (ast.Tuple, ast.List)) and node.elts:
            # the transport column's shape: code 0 (never written) as None or "", then names
            values = [e.value if isinstance(e, ast.Constant) else ... for e in node.elts]
            if values[0] in (None, "") and TRANSPORT_NAMES.intersection(v for v in values[1:] if type(v) is str):
                found.append(f"{where}: transport codes listed (use mavscope.native.core.COLUMN_TRANSPORTS)")
        elif isinstance(node, ast.ImportFrom) and node.module == "mavscope" and any(
                a.name == "_native" for a in node.names):
            found.append(f"{where}: imports the extension (import it from mavscope.native.core)")
        elif isinstance(node, ast.Import) and any(a.name == "mavscope._native" for a in node.names):
            found.append(f"{where}: imports the extension (import it from mavscope.native.core)")
    for n, line in enumerate(text.splitlines(), 1):
        if HEADER_ENUMS.search(line):
            found.append(f"{path.relative_to(root)}:{n}: a C header's numbering cited (take it from the extension)")
    return sorted(found, key=lambda f: int(f.split(":")[1]))


def test_the_contract_constants_have_one_definition() -> None:
    copies = [c for p in sorted(PACKAGE.rglob("*.py")) if p != CORE for c in _copies(p)]
    assert copies == [], "\n".join(copies)


def test_the_check_finds_each_kind_of_copy(tmp_path: Path) -> None:
    """The scan above finds every form it looks for (a check that could not fail would pass on anything)."""
    bad = tmp_path / "copy.py"
    bad.write_text('"""doc: MAVSCOPE_PURE is fine here."""\n'
                   'from mavscope import _native\n'
                   'import mavscope._native\n'
                   'PURE_ENV = "MAVSCOPE_PURE"\n'
                   'KINDS = {"pcap": 1, "pcapng": 2}\n'
                   'T = {1: "udp", 2: "tlog"}\n'
                   'N = (None, "udp", "tlog")\n'
                   'X = 3  # capture.h MS_KIND_*\n', encoding="utf-8")
    found = _copies(bad, tmp_path)
    assert [f.split(": ", 1)[1].split(" (")[0] for f in found] == [
        "imports the extension", "imports the extension", "the string MAVSCOPE_PURE", "capture kinds numbered",
        "transports numbered", "transport codes listed", "a C header's numbering cited"], found


def _stub_names(body: list[ast.stmt]) -> set[str]:
    """The public names a stub's module or class body defines."""
    names = set()
    for node in body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return {n for n in names if not n.startswith("_")}


def test_the_stub_names_what_the_built_module_has() -> None:
    """Every public name of the built extension (module and each type) is in mavscope/_native.pyi, and the
    stub names nothing the module lacks."""
    native = pytest.importorskip("mavscope._native", reason="the native extension is not built")
    tree = ast.parse(STUB.read_text(encoding="utf-8"))
    built = {n for n in dir(native) if not n.startswith("_")}
    assert _stub_names(tree.body) == built
    for cls in (n for n in tree.body if isinstance(n, ast.ClassDef)):
        typ = getattr(native, cls.name)
        assert isinstance(typ, type), cls.name
        have = {n for n in dir(typ) if not n.startswith("_")}
        assert _stub_names(cls.body) == have, cls.name


def test_the_constants_are_the_extensions() -> None:
    """core's tables are read from the extension's own constants (the headers' enums)."""
    native = pytest.importorskip("mavscope._native", reason="the native extension is not built")
    from mavscope.native import core

    assert dict(core.KINDS) == {"pcap": native.KIND_PCAP, "pcapng": native.KIND_PCAPNG, "tlog": native.KIND_TLOG,
                                "raw": native.KIND_RAW}
    assert core.COLUMN_TRANSPORTS[native.COLUMN_TRANSPORT_UDP] == "udp"
    assert core.COLUMN_TRANSPORTS[native.COLUMN_TRANSPORT_TLOG] == "tlog"
    assert core.COLUMN_TRANSPORTS[0] is None  # columns.h: 0 is never written
    # the note column's bits, one each (columns.h MS_NOTE_*)
    bits = (core.NOTE_UNSIGNED, core.NOTE_V1, core.NOTE_BAD_CRC)
    assert bits == (native.NOTE_UNSIGNED, native.NOTE_V1, native.NOTE_BAD_CRC)
    assert sorted(bits) == [1, 2, 4]
