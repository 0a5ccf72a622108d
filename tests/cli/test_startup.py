"""Start-up: only the module of the command being run is imported; every command's parser and help work.

`mavscope --help` lists the commands from mavscope.cli.COMMANDS without importing any command module
(each pulls in the pipeline, filters, security or rich tables); `mavscope stats FILE` imports stats and
what it needs, not the TUI's or live capture's modules.
"""

from __future__ import annotations

import argparse
import io
import subprocess
import sys

import pytest

from mavscope.cli import COMMANDS, Env, build_parser, main
from mavscope.errors import UsageError
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


def _full_parsers() -> tuple[argparse.ArgumentParser, dict[str, argparse.ArgumentParser]]:
    """The parser as it was before lazy imports: every command's module imported and its parser built."""
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, dict(commands.choices)


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_command_help_is_the_full_parsers(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    """`mavscope CMD --help` (only CMD's module imported) prints what the parser of every command prints."""
    expected = _full_parsers()[1][name].format_help()
    with pytest.raises(SystemExit) as stop:
        main([name, "--help"], Env(environ={}))
    assert stop.value.code == 0
    assert capsys.readouterr().out == expected


def test_the_top_level_help_is_the_full_parsers(capsys: pytest.CaptureFixture[str]) -> None:
    expected = _full_parsers()[0].format_help()
    with pytest.raises(SystemExit) as stop:
        main(["--help"], Env(environ={}))
    assert stop.value.code == 0
    assert capsys.readouterr().out == expected


@pytest.mark.parametrize("argv", [[name, "--no-such-option"] for name in COMMANDS]
                         + [["no-such-command"], ["read", "-T", "yaml", "x.pcap"], ["read", "-c", "0", "x"]])
def test_usage_errors_are_the_full_parsers(argv: list[str]) -> None:
    """Same one-line error and exit status 2 as the full parser gives (its UsageError, as main reports it)."""
    with pytest.raises(UsageError) as error:
        _full_parsers()[0].parse_args(argv)
    out, err = io.StringIO(), io.StringIO()
    assert main(argv, Env(stdout=out, stderr=err, environ={})) == 2
    assert (out.getvalue(), err.getvalue()) == ("", f"mavscope: {error.value}\n")


def test_native_jsonl_imports_no_filter_printer_or_xml_parser() -> None:
    """`read -T jsonl` on the native engine, dialect cache warm: no display filter compiler, no Python
    printer, no pymavlink XML parser (the modules only the Python path or a cache miss needs)."""
    from mavscope.native.core import engine

    if engine({}) != "native":
        pytest.skip("the native extension is not built")
    run = ("import os\nfrom mavscope.cli import Env, main\n"
           "main(['read', 'captures/px4_sitl.tlog', '-T', 'jsonl'], Env(stdout=open(os.devnull, 'w'), environ={}))")
    imported_after(run)  # fills the dialect cache (the session's, from the environment) if it is cold
    probe = run + "\nimport sys\nprint(' '.join(m for m in sys.modules if m.startswith(('mavscope.', 'pymavlink.'))))"
    proc = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    modules = set(proc.stdout.split())
    assert "mavscope.native.walk" in modules  # the probe ran the native path
    assert not modules & {"mavscope.filter", "mavscope.filter.compiler", "mavscope.output.printer",
                          "mavscope.output.capture_out", "pymavlink.generator.mavparse"}
