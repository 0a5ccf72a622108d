"""Start-up: only the module of the command being run is imported; every command's parser and help work.

`mavscope --help` lists the commands from mavscope.cli.COMMANDS without importing any command module
(each pulls in the pipeline, filters, security or rich tables); `mavscope stats FILE` imports stats and
what it needs, not the TUI's or live capture's modules.
"""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from mavscope.cli import COMMANDS, Env, build_parser, main
from tests.conftest import ROOT


def imported_after(code: str) -> set[str]:
    """The mavscope.commands modules a fresh interpreter has imported after running `code`."""
    probe = (code + "\nimport sys\n"
             "print(' '.join(sorted(m for m in sys.modules if m.startswith('mavscope.commands.'))))")
    proc = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return set(proc.stdout.split())


def test_help_imports_no_command_module() -> None:
    code = "from mavscope.cli import build_parser\nbuild_parser(argv=['--help'])"
    assert imported_after(code) == set()


def test_a_command_imports_its_own_module_only() -> None:
    code = "from mavscope.cli import build_parser\nbuild_parser(argv=['stats', 'x.pcap', '--json'])"
    # stats and the helpers it imports itself (read by hand from its imports)
    assert imported_after(code) == {"mavscope.commands.stats", "mavscope.commands.analysis_common",
                                    "mavscope.commands.common"}


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_command_has_its_help(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        main([name, "--help"], Env(environ={}))
    assert stop.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: mavscope {name} ")
    assert "-h, --help" in out


def test_the_top_level_help_lists_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--help"], Env(environ={}))
    out = " ".join(capsys.readouterr().out.split())
    for name, (_, help_text) in COMMANDS.items():
        assert f"{name} {' '.join(help_text.split())}" in out


def test_the_full_parser_builds_every_command() -> None:
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert list(commands.choices) == list(COMMANDS)
    for name, sub in commands.choices.items():
        assert callable(sub.get_default("run")), name  # register() ran: the command can run
