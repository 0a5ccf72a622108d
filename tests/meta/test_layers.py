"""The house rules the layout depends on: imports point down the data path, no import cycle (lazy imports
included), the core never imports a front end, rich, Textual or argparse, and no module is over 500 lines.

The data path, from the bottom (docs/architecture.md):

    base (errors, notes, endpoint, wire) -> capture, live -> transport -> mavlink -> pipeline (dissector,
    options) -> security -> fields, filter -> pipeline.session -> analysis -> browse -> output, cli,
    commands, tui

A module may import from its own layer or any layer below it. `pipeline.session` is the assembly point
that composes the stages after the dissector, so it sits above security and filter.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.conftest import ROOT

PACKAGE = ROOT / "mavscope"
MAX_LINES = 500

# (module prefix, layer): the longest matching prefix decides.
LAYERS: tuple[tuple[str, int], ...] = (
    ("mavscope", 0),  # the package itself (__init__: the version)
    ("mavscope.errors", 0),
    ("mavscope.notes", 0),
    ("mavscope.endpoint", 0),
    ("mavscope.wire", 0),
    ("mavscope.capture", 1),
    ("mavscope.live", 1),
    ("mavscope.transport", 2),
    ("mavscope.mavlink", 3),
    ("mavscope.pipeline", 4),
    ("mavscope.security", 5),
    ("mavscope.fields", 6),
    ("mavscope.filter", 6),
    ("mavscope.pipeline.session", 7),
    ("mavscope.analysis", 8),
    ("mavscope.rules", 8),  # detection rules as data: display filters over the analyses' vehicle state
    ("mavscope.browse", 9),
    ("mavscope.export", 9),  # captures into a columnar dataset: builds on pipeline.session and the analyses
    ("mavscope.output", 10),
    ("mavscope.report", 10),  # the incident report (HTML, JSON): over the analyses and output's helpers
    # mavscope/native/: the glue to the C extension, each module in the layer of what it serves. The
    # package and its core (the extension's one import, the engine choice, the contract's constants: they
    # name transport.base's transports) and the column chunk's numpy views import nothing above transport.
    ("mavscope.native", 2),
    ("mavscope.native.core", 2),
    ("mavscope.native.chunk", 2),
    ("mavscope.native.table_blob", 3),  # the dialect's layouts as the blob C takes (from mavlink's MessageDefs)
    ("mavscope.native.tables", 4),  # the dialect's compiled layout table: read, stats, export, the TUI's index
    ("mavscope.native.windows", 7),  # the native walker's windows: the dissector and security stage composed
    ("mavscope.native.index", 9),  # the TUI's index filled from native chunks (browse's layer)
    ("mavscope.native.columns", 9),  # the export's Arrow columns from native chunks (the export's layer)
    ("mavscope.native.export", 9),  # the export's native batch source
    # The native engine of `read -T jsonl` composes the dissector and the security stage (as
    # pipeline.session does) and writes output.jsonout's JSON Lines, so it sits with the front ends.
    ("mavscope.native.walk", 10),
    ("mavscope.native.summary", 10),
    ("mavscope.native.live", 10),
    # The C extension (not a .py: listed for the record) imports nothing; mavscope.native.core imports it.
    ("mavscope._native", 2),
    ("mavscope.cli", 10),
    ("mavscope.commands", 10),
    ("mavscope.tui", 10),
    ("mavscope.__main__", 10),
)
FRONT_END = 10
FRONT_END_ONLY = ("rich", "textual", "argparse")


def layer(module: str) -> int:
    best = max((p for p, _ in LAYERS if module == p or module.startswith(p + ".")), key=len)
    return dict(LAYERS)[best]


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imports(module: str) -> set[str]:
    """Every module `module` imports, at the top or inside a function (lazy), resolved to a module name."""
    path = MODULES[module]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
            for a in node.names:  # `from pkg import sub` imports the submodule pkg.sub
                out.add(f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base)
    return out


GRAPH = {m: {i for i in imports(m) if i in MODULES and i != m} for m in MODULES}


def test_every_import_points_down_the_data_path() -> None:
    wrong = [f"{m} (layer {layer(m)}) imports {i} (layer {layer(i)})"
             for m, deps in GRAPH.items() for i in sorted(deps) if layer(i) > layer(m)]
    assert not wrong, "\n".join(wrong)


def test_the_core_never_imports_a_front_end_or_its_libraries() -> None:
    wrong = [f"{m} imports {i}" for m in MODULES if layer(m) < FRONT_END
             for i in sorted(imports(m)) if i.split(".")[0] in FRONT_END_ONLY]
    assert not wrong, "\n".join(wrong)


def test_no_import_cycle() -> None:
    cycles: list[list[str]] = []
    state: dict[str, int] = {}  # 1: on the stack, 2: done
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for d in sorted(GRAPH[m]):
            if state.get(d) == 1:
                cycles.append(stack[stack.index(d):] + [d])
            elif d not in state:
                visit(d)
        stack.pop()
        state[m] = 2

    for m in sorted(GRAPH):
        if m not in state:
            visit(m)
    assert not cycles, "\n".join(" -> ".join(c) for c in cycles)


# git-ignored folders of things made or installed (benchmarks/out holds the peers' venv): not our modules
GENERATED = frozenset({"out", ".venv", "build", "__pycache__"})


@pytest.mark.parametrize("folder", ["mavscope", "scripts", "benchmarks", "tests"])
def test_no_module_over_500_lines(folder: str) -> None:
    long = [f"{p.relative_to(ROOT)}: {n} lines" for p in sorted((ROOT / folder).rglob("*.py"))
            if not GENERATED.intersection(p.relative_to(ROOT).parts)
            and (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES]
    assert not long, "\n".join(long)


def test_the_layer_check_sees_what_it_should() -> None:
    """The checks above can fail: a lazy import is found, and a front-end import in the core would be seen."""
    assert "mavscope.security.stage" in GRAPH["mavscope.pipeline.session"]
    assert "mavscope.filter" in GRAPH["mavscope.pipeline.session"]
    assert layer("mavscope.pipeline.session") > layer("mavscope.security.stage") > layer("mavscope.pipeline.dissect")
    assert layer("mavscope.fields.registry") < FRONT_END <= layer("mavscope.tui.app")
    lazy = {i for i in imports("mavscope.commands.read")}
    assert "mavscope.pipeline.dissect" in lazy
