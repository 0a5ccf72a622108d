"""`mavscope live` with read's tshark options (-T fields with -e, -z), over loopback with both engines (the
`engine` fixture of test_live.py, imported here)."""

from __future__ import annotations

import re
import socket

from mavscope.cli import ExitStatus
from tests.live.test_live import LiveRun, engine  # noqa: F401  (the fixture: every test with both engines)
from tests.support import builders


def test_fields_and_statistics_live() -> None:
    """`live -T fields -e ... -z mavlink,msgs -z conv,udp`: read's fields lines, one per datagram as it
    comes (two frames in one datagram share a line), then the statistics of every frame received, whatever
    -Y shows. Expected by hand from the datagrams sent: seq 0 HEARTBEAT alone, then seq 1 and 2 together;
    -Y keeps only the ATTITUDE of the second datagram, the statistics count all three frames."""
    run = LiveRun("--udp", "127.0.0.1:0", "-T", "fields", "-e", "mavlink.seq", "-e", "mavlink.msgname",
                  "-e", "ATTITUDE.roll", "-c", "3", "--duration", "8", "-z", "mavlink,msgs", "-z", "conv,udp")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(builders.heartbeat(builders.mav2(1, 1, 0)), ("127.0.0.1", run.port))
        s.sendto(builders.heartbeat(builders.mav2(1, 1, 1)) + builders.attitude(builders.mav2(1, 1, 2), 5, 0.5),
                 ("127.0.0.1", run.port))
    status, out, err = run.join()
    assert status == ExitStatus.OK, err
    lines = out.splitlines()
    assert lines[:2] == ["0\tHEARTBEAT\t", "1,2\tHEARTBEAT,ATTITUDE\t0.5"]
    stats = "\n".join(lines[2:])
    assert re.search(r"1/1\s+HEARTBEAT\s+2\s", stats) and "127.0.0.1" in stats  # (mavlink,msgs; conv,udp)
    filtered = LiveRun("--udp", "127.0.0.1:0", "-T", "fields", "-e", "mavlink.seq", "-Y", "ATTITUDE", "-c", "1",
                       "--duration", "8", "-z", "mavlink,msgs")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(builders.heartbeat(builders.mav2(1, 1, 0)), ("127.0.0.1", filtered.port))
        s.sendto(builders.heartbeat(builders.mav2(1, 1, 1)) + builders.attitude(builders.mav2(1, 1, 2), 5, 0.5),
                 ("127.0.0.1", filtered.port))
    status, out, err = filtered.join()
    assert status == ExitStatus.OK, err
    assert out.splitlines()[0] == "2"
    # both HEARTBEATs counted, though -Y showed neither; the ATTITUDE once
    assert re.search(r"1/1\s+HEARTBEAT\s+2\s", out) and re.search(r"1/1\s+ATTITUDE\s+1\s", out)
