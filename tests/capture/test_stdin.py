"""`mavscope read -` (and every command's `-`): a capture from a pipe, as from the file, in bounded memory.

The reference is the same command on the file itself (`MAVSCOPE_PURE=1`: standard input is read by the
Python readers, so the file is read by the same ones): for every bundled capture and a few real ones
(pcap, pcapng, tlog, raw, damaged ones included) the frames (`read -T jsonl`, every offset and note) and
`stats --json` (but its `file`) must be equal, the capture given on a pipe (`subprocess` writes it, so
the reader never sees a regular file). A capture of about 60 MB streamed through a pipe holds the reader to
a bounded window (peak RSS of the child under 200 MB: 84 MB measured, the capture being 60 MB), every frame
of it counted.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from mavscope.capture.pcap import PcapReader
from mavscope.capture.writer import PcapWriter
from tests.conftest import CAPTURES, REAL_CAPTURES, ROOT

PURE = {"MAVSCOPE_PURE": "1"}
NAMES = sorted(p.name for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw", ".bin"))


def _run(argv: list[str], stdin: bytes | None = None) -> subprocess.CompletedProcess[bytes]:
    import os

    env = {**os.environ, **PURE}
    return subprocess.run([sys.executable, "-m", "mavscope", *argv], input=stdin, capture_output=True, cwd=ROOT,
                          env=env, timeout=600, check=False)


@pytest.mark.parametrize("name", NAMES)
def test_a_pipe_gives_the_files_frames(name: str) -> None:
    path = CAPTURES / name
    data = path.read_bytes()
    want, got = _run(["read", str(path), "-T", "jsonl"]), _run(["read", "-", "-T", "jsonl"], data)
    assert got.returncode == want.returncode == 0, got.stderr[-300:]
    assert got.stdout == want.stdout
    a = json.loads(_run(["stats", str(path), "--json"]).stdout)
    b = json.loads(_run(["stats", "-", "--json"], data).stdout)
    a.pop("file"), b.pop("file")
    assert a == b


def test_real_captures_on_a_pipe() -> None:
    if not REAL_CAPTURES.is_dir():
        pytest.skip("../shared/real-captures is absent")
    for name in ("ardusub_log_tools_small.tlog", "serial_dump.raw", "ipal_transcriber_MAVLink.pcap"):
        path = REAL_CAPTURES / name
        if path.exists():
            want, got = _run(["read", str(path), "-T", "jsonl"]), _run(["read", "-", "-T", "jsonl"], path.read_bytes())
            assert got.stdout == want.stdout and got.returncode == 0, name


def test_w_needs_a_file_for_packet_captures(tmp_path: Path) -> None:
    got = _run(["read", "-", "-w", str(tmp_path / "o.pcap")], (CAPTURES / "px4_sitl_udp.pcap").read_bytes())
    assert got.returncode == 2 and b"cannot be read again" in got.stderr


def test_a_long_stream_in_bounded_memory() -> None:
    """About 60 MB of pcap (the PX4 capture's records again and again) written to the child's standard input
    by a thread, never to a file; `-q` so that the output does not dominate."""
    with PcapReader(CAPTURES / "px4_sitl_udp.pcap") as r:
        records = [(rec.time, rec.data) for rec in r]
        linktype = r.linktype
    import io
    import os

    buf = io.BytesIO()
    with PcapWriter(buf, linktype) as w:
        for t, d in records:
            w.write(t, d)
    head, body = buf.getvalue()[:24], buf.getvalue()[24:]
    copies = 60_000_000 // len(body)
    # the child's own peak RSS, from a wrapper whose only child it is (this process's children are many)
    wrapper = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]); "
               "print('peak', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
               "sys.exit(r.returncode)")
    proc = subprocess.Popen([sys.executable, "-c", wrapper, sys.executable, "-m", "mavscope", "read", "-", "-q",
                             "-z", "mavlink,links"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, cwd=ROOT, env={**os.environ, **PURE})
    assert proc.stdin is not None

    def feed() -> None:
        assert proc.stdin is not None
        proc.stdin.write(head)
        for _ in range(copies):
            proc.stdin.write(body)
        proc.stdin.close()

    writer = threading.Thread(target=feed)
    writer.start()
    assert proc.stdout is not None and proc.stderr is not None
    out, err = proc.stdout.read(), proc.stderr.read()  # (not communicate: it would close stdin at once)
    proc.wait(timeout=1200)
    writer.join()
    assert proc.returncode == 0, err[-300:]
    peak_mb = int(err.split(b"peak ")[-1]) / 1024
    assert peak_mb < 200, peak_mb
    assert f"{1303 * copies:>9}".encode() in out  # 1/1's frames, every copy counted
