"""Both engines of `read -T jsonl` (and of the summary lines of `read FILE`) side by side.

Through the command line (the `cli` fixture): `pure(cli, ...)` with MAVSCOPE_PURE=1, `native(cli, ...)`
without it, `same(cli, ...)` runs both and asserts equal stdout, stderr and exit status. Through the API
(for the walk's counters and the threaded writer): `pure_output` is the Python pipeline as `read` runs it
(Dissector, SecurityStage, jsonl_bytes, problems through `Problems`), `native_output` is
mavscope.native.write_jsonl.
"""

from __future__ import annotations

import io
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from mavscope.capture.detect import open_capture
from mavscope.cli import Env
from mavscope.commands.common import Problems
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.output.jsonout import jsonl_bytes
from mavscope.output.text import summary_line
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.security.keys import KeyMaterial, SigningKey
from mavscope.security.stage import SecurityStage
from tests.conftest import Cli, CliResult
from tests.native.build import KEY, KEY_SPEC

PURE = {"MAVSCOPE_PURE": "1"}
KEY_OPTIONS = {"none": [], "key": ["--key", KEY_SPEC], "leaked": ["--use-leaked-keys"]}


def pure(cli: Cli, path: str | Path, *extra: str, fmt: tuple[str, ...] = ("-T", "jsonl")) -> CliResult:
    return cli("read", path, *fmt, *extra, environ=PURE)


def native(cli: Cli, path: str | Path, *extra: str, fmt: tuple[str, ...] = ("-T", "jsonl")) -> CliResult:
    return cli("read", path, *fmt, *extra, environ={})


def same(cli: Cli, path: str | Path, *extra: str, fmt: tuple[str, ...] = ("-T", "jsonl")) -> CliResult:
    """Both engines on `path`: stderr, stdout and exit status must be equal (the native result). `fmt`:
    the output options (() for the summary lines)."""
    p = pure(cli, path, *extra, fmt=fmt)
    n = native(cli, path, *extra, fmt=fmt)
    assert n.err == p.err
    assert n.out == p.out
    assert n.status == p.status
    return n


@contextmanager
def capture_file(data: bytes, suffix: str = ".cap") -> Iterator[str]:
    """`data` in a temporary file (named `*suffix`), deleted afterwards: its path."""
    fd, path = tempfile.mkstemp(suffix=suffix)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        yield path
    finally:
        os.unlink(path)


def material(kind: str | KeyMaterial) -> KeyMaterial:
    """"none": no key; "key": KEY as a signing key (as `--key KEY_SPEC` makes it); "leaked": --use-leaked-keys;
    or the KeyMaterial given."""
    if isinstance(kind, KeyMaterial):
        return kind
    if kind == "key":
        return KeyMaterial(signing=[SigningKey("key1", KEY)])  # the name the command line gives it
    if kind == "leaked":
        return KeyMaterial(use_leaked_keys=True)
    return KeyMaterial()


def pure_output(path: str | Path, dialect: Dialect, keys: str | KeyMaterial = "none",
                render: Callable[[Frame], bytes] = jsonl_bytes, count: int | None = None) -> tuple[bytes, str]:
    """(stdout, stderr) of `read -T jsonl` on the pure-Python path, through the API (or, with `render`, of
    the lines it makes per frame: summary_render for `read FILE`; `count`: stop after that many, as -c)."""
    err = io.StringIO()
    problems = Problems(Env(stdout=io.StringIO(), stderr=err, environ={}), str(path))
    out = io.BytesIO()
    stage = SecurityStage(material(keys))
    shown = 0
    with open_capture(path) as reader:
        for item in stage.run(Dissector(dialect).run(reader)):
            if type(item) is Anomaly:
                problems.anomaly(item)
                continue
            if item.notes:
                problems.frame(item)
            out.write(render(item))
            shown += 1
            if shown == count:
                break
    problems.close()
    return out.getvalue(), err.getvalue()


def summary_render(path: str | Path, dialect: Dialect) -> Callable[[Frame], bytes]:
    """The summary line of `read FILE` as the pure path prints it: times relative to the first record's."""
    with open_capture(path) as reader:
        first = next(iter(reader), None)
    t0 = None if first is None else first.time
    return lambda frame: (summary_line(frame, dialect, t0) + "\n").encode()


def native_output(path: str | Path, dialect: Dialect, keys: str | KeyMaterial = "none", threaded: bool = False,
                  window: int | None = None) -> tuple[bytes, str, dict[str, int]]:
    """(stdout, stderr, walk counters) of `read -T jsonl` on the native path, through the API (the walker
    reading `window` bytes at a time when given)."""
    from mavscope.native.walk import write_jsonl

    return _native(lambda *a, **k: write_jsonl(*a, **k), path, dialect, keys, threaded, window)


def native_summary_output(path: str | Path, dialect: Dialect, keys: str | KeyMaterial = "none",
                          threaded: bool = False, window: int | None = None,
                          count: int | None = None) -> tuple[bytes, str, dict[str, int]]:
    """(stdout, stderr, walk counters) of `read FILE` (summary lines) on the native path, through the API."""
    from mavscope.native.summary import write_summary

    with open_capture(path) as reader:
        first = next(iter(reader), None)
    t0 = None if first is None else first.time

    def write(path: str | Path, dialect: Dialect, stage: SecurityStage, out: io.BytesIO, problems: Problems,
              **options: object) -> dict[str, int]:
        return write_summary(path, dialect, stage, out, problems, t0, count, **options)  # type: ignore[arg-type]

    return _native(write, path, dialect, keys, threaded, window)


def _native(write: Callable[..., dict[str, int]], path: str | Path, dialect: Dialect, keys: str | KeyMaterial,
            threaded: bool, window: int | None) -> tuple[bytes, str, dict[str, int]]:
    from mavscope.capture.reader import WINDOW

    err = io.StringIO()
    problems = Problems(Env(stdout=io.StringIO(), stderr=err, environ={}), str(path))
    out = io.BytesIO()
    stats = write(path, dialect, SecurityStage(material(keys)), out, problems, threaded=threaded,
                  window=window or WINDOW)
    problems.close()
    return out.getvalue(), err.getvalue(), stats
