"""Both engines of `read -T jsonl` side by side.

Through the command line (the `cli` fixture): `pure(cli, ...)` with MAVSCOPE_PURE=1, `native(cli, ...)`
without it, `same(cli, ...)` runs both and asserts equal stdout, stderr and exit status. Through the API
(for the walk's counters and the threaded writer): `pure_output` is the Python pipeline as `read` runs it
(Dissector, SecurityStage, jsonl_bytes, problems through `Problems`), `native_output` is
mavscope.native.write_jsonl.
"""

from __future__ import annotations

import io
from pathlib import Path

from mavscope.capture.detect import open_capture
from mavscope.cli import Env
from mavscope.commands.common import Problems
from mavscope.mavlink.dialect import Dialect
from mavscope.output.jsonout import jsonl_bytes
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.security.keys import KeyMaterial, SigningKey
from mavscope.security.stage import SecurityStage
from tests.conftest import Cli, CliResult
from tests.native.build import KEY, KEY_SPEC

PURE = {"MAVSCOPE_PURE": "1"}
KEY_OPTIONS = {"none": [], "key": ["--key", KEY_SPEC], "leaked": ["--use-leaked-keys"]}


def pure(cli: Cli, path: str | Path, *extra: str) -> CliResult:
    return cli("read", path, "-T", "jsonl", *extra, environ=PURE)


def native(cli: Cli, path: str | Path, *extra: str) -> CliResult:
    return cli("read", path, "-T", "jsonl", *extra, environ={})


def same(cli: Cli, path: str | Path, *extra: str) -> CliResult:
    """Both engines on `path`: stderr, stdout and exit status must be equal (the native result)."""
    p = pure(cli, path, *extra)
    n = native(cli, path, *extra)
    assert n.err == p.err
    assert n.out == p.out
    assert n.status == p.status
    return n


def material(kind: str) -> KeyMaterial:
    """"none": no key; "key": KEY as a signing key (as `--key KEY_SPEC` makes it); "leaked": --use-leaked-keys."""
    if kind == "key":
        return KeyMaterial(signing=[SigningKey("key1", KEY)])  # the name the command line gives it
    if kind == "leaked":
        return KeyMaterial(use_leaked_keys=True)
    return KeyMaterial()


def pure_output(path: str | Path, dialect: Dialect, keys: str = "none") -> tuple[bytes, str]:
    """(stdout, stderr) of `read -T jsonl` on the pure-Python path, through the API."""
    err = io.StringIO()
    problems = Problems(Env(stdout=io.StringIO(), stderr=err, environ={}), str(path))
    out = io.BytesIO()
    stage = SecurityStage(material(keys))
    with open_capture(path) as reader:
        for item in stage.run(Dissector(dialect).run(reader)):
            if type(item) is Anomaly:
                problems.anomaly(item)
                continue
            if item.notes:
                problems.frame(item)
            out.write(jsonl_bytes(item))
    problems.close()
    return out.getvalue(), err.getvalue()


def native_output(path: str | Path, dialect: Dialect, keys: str = "none", threaded: bool = False,
                  window: int | None = None) -> tuple[bytes, str, dict[str, int]]:
    """(stdout, stderr, walk counters) of `read -T jsonl` on the native path, through the API (the walker
    reading `window` bytes at a time when given)."""
    from mavscope.capture.reader import WINDOW
    from mavscope.native import write_jsonl

    err = io.StringIO()
    problems = Problems(Env(stdout=io.StringIO(), stderr=err, environ={}), str(path))
    out = io.BytesIO()
    stats = write_jsonl(path, dialect, SecurityStage(material(keys)), out, problems, threaded=threaded,
                        window=window or WINDOW)
    problems.close()
    return out.getvalue(), err.getvalue(), stats
