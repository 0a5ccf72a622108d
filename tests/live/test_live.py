"""`mavscope live` with real senders over loopback: pymavlink `udpout` connections, a relay, SIGTERM.

Each test runs the real entry point (in a thread with a fake environment, or as a subprocess when a
signal or a real pipe is involved) on an ephemeral port of 127.0.0.1, stops it with -c/--duration or a
signal, and checks the frames in the JSON output and in the pcap it wrote (read back by mavscope's reader
and by tshark).
"""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from mavscope.capture.detect import open_capture
from mavscope.cli import Env, ExitStatus, main
from tests.conftest import ROOT
from tests.support import pmav

SUMMARY = re.compile(r"^mavscope: live: (\d+) frames, (\d+) bytes, (\d+) dropped \((\d+) queue, (\d+) kernel\)$")
# the summary when the stop came before every datagram received was decoded (a loaded machine): they are
# written to -w's pcap all the same, and counted here
SUMMARY_LATE = re.compile(SUMMARY.pattern[:-1] + r"(?:; (\d+) received after the stop written but not decoded)?$")
LISTENING = re.compile(r"listening on udp (\S+):(\d+)")


@pytest.fixture(autouse=True, params=["native", "pure-python"])
def engine(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Every test with both engines: the native one (batched receive, the C walker writing the lines where
    the options allow) and MAVSCOPE_PURE=1 (recvmsg per datagram, the Python pipeline)."""
    if request.param == "pure-python":
        monkeypatch.setenv("MAVSCOPE_PURE", "1")
    else:
        monkeypatch.delenv("MAVSCOPE_PURE", raising=False)
    return str(request.param)


class LiveRun:
    """`main(["live", ...])` on a thread; the port it bound is read from its first stderr line."""

    def __init__(self, *argv: str) -> None:
        self.out, self.err = io.StringIO(), io.StringIO()
        self.status: int | None = None
        self.thread = threading.Thread(target=self._main, args=(list(argv),), daemon=True)
        self.thread.start()
        self.port = self._wait_port()

    def _main(self, argv: list[str]) -> None:
        self.status = main(["live", *argv], Env(stdout=self.out, stderr=self.err))

    def _wait_port(self) -> int:
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            m = LISTENING.search(self.err.getvalue())
            if m:
                return int(m.group(2))
            if not self.thread.is_alive():
                raise AssertionError(f"live exited early: {self.err.getvalue()}")
            time.sleep(0.01)
        raise AssertionError("live did not start listening")

    def join(self, timeout: float = 10) -> tuple[int, str, str]:
        self.thread.join(timeout)
        assert not self.thread.is_alive(), "live did not stop"
        assert self.status is not None
        return self.status, self.out.getvalue(), self.err.getvalue()


def send_pymavlink(port: int) -> list[tuple[int, str, str]]:
    """What the issue asks for: STATUSTEXT from system 100 through a pymavlink `udpout` connection (as a
    mavlink-router sender script does), and HEARTBEATs from several systems. Returns (sysid, msgname, text)."""
    from pymavlink import mavutil

    sent: list[tuple[int, str, str]] = []
    conns = []
    status = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=100)
    conns.append(status)
    for i in range(5):
        text = f"mavscope live {i}"
        status.mav.statustext_send(mavutil.mavlink.MAV_SEVERITY_INFO, text.encode())
        sent.append((100, "STATUSTEXT", text))
    for sysid in (1, 2, 3, 42):
        hb = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=sysid)
        conns.append(hb)
        for _ in range(2):
            hb.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_QUADROTOR, mavutil.mavlink.MAV_AUTOPILOT_PX4, 81, 0, 4)
            sent.append((sysid, "HEARTBEAT", ""))
    for c in conns:
        c.close()
    return sent


def _frames_of(out: str) -> list[dict[str, object]]:
    return [json.loads(line) for line in out.splitlines()]


def _tshark_fields(pcap: Path, *fields: str) -> list[list[str]]:
    exe = shutil.which("tshark")
    if exe is None:
        pytest.skip("tshark is not installed (scripts/install-test-tools.sh installs it)")
    cmd = [exe, "-n", "-r", str(pcap), "-T", "fields", "-o", "udp.check_checksum:TRUE"]
    for f in fields:
        cmd += ["-e", f]
    env = dict(os.environ, WIRESHARK_CONFIG_DIR=str(pcap.parent / "wireshark-config"))
    (pcap.parent / "wireshark-config").mkdir(exist_ok=True)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60, env=env, check=False)
    assert proc.returncode == 0, proc.stderr
    return [line.split("\t") for line in proc.stdout.splitlines()]


def test_pymavlink_senders_every_frame_in_json_and_pcap(tmp_path: Path) -> None:
    pcap = tmp_path / "live.pcap"
    run = LiveRun("--udp", "127.0.0.1:0", "-T", "jsonl", "-w", str(pcap), "-c", "13", "--duration", "8")
    sent = send_pymavlink(run.port)
    status, out, err = run.join()
    assert status == ExitStatus.OK
    frames = _frames_of(out)
    assert [(f["sysid"], f["msgname"], (f["fields"] or {}).get("text", "") if f["msgname"] == "STATUSTEXT" else "")
            for f in frames] == sent
    assert [f["frame"] for f in frames] == list(range(1, 14))  # numbered in arrival order
    assert all(f["crc_status"] == "ok" and f["transport"] == "udp" for f in frames)
    assert all(f["dst"] == f"127.0.0.1:{run.port}" for f in frames)
    assert len({f["src"] for f in frames if f["sysid"] == 100}) == 1
    times = [f["time"] for f in frames]
    assert times == sorted(times) and abs(times[0] - time.time()) < 30
    last = err.splitlines()[-1]
    m = SUMMARY.match(last)
    assert m and m.group(1) == "13" and m.group(3) == "0", err

    # the pcap holds every datagram: mavscope's reader, `mavscope read`, and tshark agree
    with open_capture(str(pcap)) as reader:
        records = list(reader)
    assert len(records) == 13 and all(r.linktype == 1 for r in records)
    rs, rout, _ = _run_cli("read", str(pcap), "-T", "jsonl")
    assert rs == ExitStatus.OK
    again = _frames_of(rout)
    assert [(f["frame"], f["sysid"], f["seq"], f["src"], f["dst"]) for f in again] == [
        (f["frame"], f["sysid"], f["seq"], f["src"], f["dst"]) for f in frames]
    assert [f["time"] for f in again] == pytest.approx(times, abs=2e-6)  # pcap keeps microseconds
    rows = _tshark_fields(pcap, "frame.number", "ip.src", "udp.srcport", "udp.dstport", "udp.checksum.status",
                          "udp.length")
    assert len(rows) == 13
    assert all(r[1] == "127.0.0.1" and r[3] == str(run.port) and r[4] == "1" for r in rows)  # checksums good
    assert [r[2] for r in rows] == [f["src"].rsplit(":", 1)[1] for f in frames]  # type: ignore[union-attr]


def _run_cli(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    status = main(list(argv), Env(stdout=out, stderr=err))
    return status, out.getvalue(), err.getvalue()


def test_v2_datagrams_with_several_frames_and_garbage(tmp_path: Path) -> None:
    run = LiveRun("--udp", "127.0.0.1:0", "-T", "jsonl", "-c", "4", "--duration", "8")
    vehicle = pmav.mav2(1, 1)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(pmav.heartbeat(vehicle) + pmav.statustext(vehicle, "two in one"), ("127.0.0.1", run.port))
        bad = bytearray(pmav.heartbeat(vehicle))
        bad[-3] ^= 0x55
        s.sendto(b"junk" + bytes(bad), ("127.0.0.1", run.port))
        s.sendto(pmav.command_long_rtl(pmav.mav2(255, 190)), ("127.0.0.1", run.port))
    status, out, _ = run.join()
    assert status == ExitStatus.OK
    frames = _frames_of(out)
    assert [(f["frame"], f["index"], f["msgname"], f["crc_status"]) for f in frames] == [
        (1, 1, "HEARTBEAT", "ok"), (1, 2, "STATUSTEXT", "ok"), (2, 1, "HEARTBEAT", "bad"), (3, 1, "COMMAND_LONG", "ok")]


def test_text_output_filter_and_verbose() -> None:
    run = LiveRun("--udp", "127.0.0.1:0", "-Y", "STATUSTEXT", "-V", "-c", "1", "--duration", "8")
    sent = send_pymavlink(run.port)
    status, out, err = run.join()
    assert status == ExitStatus.OK and sent
    first = out.splitlines()[0]
    assert "STATUSTEXT" in first and "100/0" in first and "text='mavscope live 0'" in first
    assert "Frame 1:" in out  # the -V tree
    assert SUMMARY.match(err.splitlines()[-1])


def test_forward_relays_both_ways_and_decodes_both(tmp_path: Path) -> None:
    """A client talks to mavscope's port; mavscope relays to a 'vehicle' that answers every datagram."""
    vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    vehicle.bind(("127.0.0.1", 0))
    vehicle.settimeout(5)
    vport = vehicle.getsockname()[1]
    vmav = pmav.mav2(1, 1)

    def answer() -> None:
        for _ in range(3):
            try:
                _, addr = vehicle.recvfrom(65535)
            except OSError:
                return
            vehicle.sendto(pmav.heartbeat(vmav), addr)

    responder = threading.Thread(target=answer, daemon=True)
    responder.start()
    pcap = tmp_path / "relay.pcap"
    run = LiveRun("--udp", "127.0.0.1:0", "--forward", f"127.0.0.1:{vport}", "-T", "jsonl", "-c", "6",
                  "-w", str(pcap), "--duration", "8")
    gcs = pmav.mav2(255, 190)
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.settimeout(5)
    replies = []
    for _ in range(3):
        client.sendto(pmav.command_long_rtl(gcs), ("127.0.0.1", run.port))
        data, addr = client.recvfrom(65535)
        replies.append((data, addr))
    status, out, err = run.join()
    responder.join(5)
    client_port = client.getsockname()[1]
    client.close()
    vehicle.close()
    assert status == ExitStatus.OK
    assert [addr for _, addr in replies] == [("127.0.0.1", run.port)] * 3  # replies come back through the relay
    assert all(data[0] == 0xFD for data, _ in replies)
    frames = _frames_of(out)
    assert [(f["msgname"], f["sysid"]) for f in frames] == [("COMMAND_LONG", 255), ("HEARTBEAT", 1)] * 3
    up = frames[0]
    down = frames[1]
    assert up["src"] == f"127.0.0.1:{client_port}" and up["dst"] == f"127.0.0.1:{run.port}"
    assert down["src"] == f"127.0.0.1:{vport}" and str(down["dst"]).startswith("127.0.0.1:")
    assert "relayed 6 datagrams (0 could not be relayed)" in err
    rows = _tshark_fields(pcap, "udp.srcport", "udp.dstport")
    assert [r[0] for r in rows] == [str(client_port), str(vport)] * 3


def test_sigterm_and_sigint_stop_cleanly(tmp_path: Path) -> None:
    """A subprocess with stdout on a pipe: lines arrive while it runs (flushed), a signal stops it with
    the summary line, exit status 0 and a complete pcap."""
    for sig in (signal.SIGTERM, signal.SIGINT):
        pcap = tmp_path / f"sig{int(sig)}.pcap"
        proc = subprocess.Popen([sys.executable, "-m", "mavscope", "live", "--udp", "127.0.0.1:0", "-T", "jsonl",
                                 "-w", str(pcap)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT,
                                env={k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"})
        try:
            assert proc.stderr is not None and proc.stdout is not None
            m = LISTENING.search(proc.stderr.readline().decode())
            assert m, "no listening line"
            sent = send_pymavlink(int(m.group(2)))
            lines = [proc.stdout.readline() for _ in sent]  # would block forever if live did not flush
            assert all(json.loads(line)["sysid"] == sysid for line, (sysid, _, _) in zip(lines, sent))
            proc.send_signal(sig)
            rest, err = proc.communicate(timeout=10)
        finally:
            if proc.poll() is None:
                proc.kill()
        assert proc.returncode == 0, err
        assert rest == b""
        m2 = SUMMARY.match(err.decode().splitlines()[-1])
        assert m2 and int(m2.group(1)) == len(sent) and m2.group(3) == "0", err
        with open_capture(str(pcap)) as reader:
            assert len(list(reader)) == len(sent)


def test_a_second_sigterm_is_not_ignored(tmp_path: Path) -> None:
    """Issue: a second SIGTERM was ignored. Two in a row: it stops, prints its summary, exit status 0, and
    every datagram received is in the pcap (written even when the stop left it undecoded)."""
    pcap = tmp_path / "twice.pcap"
    proc = subprocess.Popen([sys.executable, "-m", "mavscope", "live", "--udp", "127.0.0.1:0", "-q", "-w", str(pcap)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    try:
        assert proc.stderr is not None
        m = LISTENING.search(proc.stderr.readline().decode())
        assert m, "no listening line"
        sent = send_pymavlink(int(m.group(2)))
        proc.send_signal(signal.SIGTERM)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)  # a guard against a hang, not a speed requirement
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    last = err.decode().splitlines()[-1]
    assert SUMMARY_LATE.match(last), err  # however far the decoding had got when the signals came
    with open_capture(str(pcap)) as reader:
        assert len(list(reader)) <= len(sent)  # what the receiver took before the second stop


def test_pcap_flushed_while_running(tmp_path: Path) -> None:
    pcap = tmp_path / "running.pcap"
    run = LiveRun("--udp", "127.0.0.1:0", "-q", "-w", str(pcap), "--duration", "3")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(pmav.heartbeat(pmav.mav2(1, 1)), ("127.0.0.1", run.port))
    time.sleep(1.5)  # at most a second after arrival, the record is in the file
    assert run.thread.is_alive()
    with open_capture(str(pcap)) as reader:
        assert len(list(reader)) == 1
    status, out, err = run.join()
    assert status == ExitStatus.OK and out == ""
    assert SUMMARY.match(err.splitlines()[-1]).group(1) == "1"  # type: ignore[union-attr]


def test_ring_keeps_at_most_n_mb(tmp_path: Path) -> None:
    pcap = tmp_path / "ring.pcap"
    n = 3000  # about 400 kB of records for a 200 kB ring
    run = LiveRun("--udp", "127.0.0.1:0", "-q", "-w", str(pcap), "--ring", "0.2", "-c", str(n), "--duration", "15")
    mav = pmav.mav2(1, 1)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for i in range(n):
            s.sendto(pmav.statustext(mav, f"ring {i:04d} " + "x" * 35), ("127.0.0.1", run.port))
            if i % 100 == 99:
                time.sleep(0.01)
    status, _, err = run.join(20)
    assert status == ExitStatus.OK, err
    older = Path(str(pcap) + ".1")
    assert pcap.exists() and older.exists()
    assert pcap.stat().st_size + older.stat().st_size <= 200_000
    # both halves are complete captures; together they hold the newest records, in order, up to the last
    numbers = []
    for path in (older, pcap):
        _, out, _ = _run_cli("read", str(path), "-T", "jsonl")
        numbers += [json.loads(line)["fields"]["text"] for line in out.splitlines()]
    idx = [int(t.split()[1]) for t in numbers]
    assert idx == list(range(idx[0], n)) and idx[0] > 0


def test_usage_errors() -> None:
    for argv, msg in [
        (["--udp", "14550", "--bpf", "udp"], "--bpf goes with --sniff"),
        (["--sniff", "lo", "--forward", "127.0.0.1:1"], "--forward goes with --udp"),
        (["--udp", "14550", "--ring", "5"], "--ring goes with -w"),
        (["--udp", "70000"], "not a UDP port"),
        (["--udp", "::1:14550"], "brackets"),
        (["--udp", "14550", "--forward", "14551"], "expected HOST:PORT"),
        (["--udp", "14550", "-c", "0"], "argument -c: a whole positive number"),
    ]:
        status, _, err = _run_cli("live", *argv)
        assert status == ExitStatus.ERROR and msg in err, (argv, err)


def test_port_in_use_is_one_line() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        status, _, err = _run_cli("live", "--udp", f"127.0.0.1:{s.getsockname()[1]}", "--duration", "1")
    assert status == ExitStatus.ERROR
    assert err.startswith("mavscope: live: cannot listen on udp 127.0.0.1:") and err.count("\n") == 1


def test_ipv6_loopback(tmp_path: Path) -> None:
    if not socket.has_ipv6:
        pytest.skip("no IPv6")
    try:
        probe = socket.socket(socket.AF_INET6, socket.SOCK_DGRAM)
        probe.bind(("::1", 0))
        probe.close()
    except OSError as e:
        pytest.skip(f"no IPv6 loopback: {e}")
    pcap = tmp_path / "v6.pcap"
    run = LiveRun("--udp", "[::1]:0", "-T", "jsonl", "-c", "1", "-w", str(pcap), "--duration", "8")
    with socket.socket(socket.AF_INET6, socket.SOCK_DGRAM) as s:
        s.sendto(pmav.heartbeat(pmav.mav2(9, 1)), ("::1", run.port))
    status, out, _ = run.join()
    assert status == ExitStatus.OK
    f = _frames_of(out)[0]
    assert f["sysid"] == 9 and f["dst"] == f"[::1]:{run.port}" and str(f["src"]).startswith("[::1]:")
    rows = _tshark_fields(pcap, "ipv6.src", "udp.dstport", "udp.checksum.status")
    assert rows == [["::1", str(run.port), "1"]]


def _have_libpcap() -> bool:
    try:
        import scapy.libs.winpcapy  # noqa: F401 - loads libpcap through ctypes
    except (OSError, ImportError):
        return False
    return True


def test_sniff_loopback_with_bpf(tmp_path: Path) -> None:
    if os.geteuid() != 0:
        pytest.skip("sniffing needs root or CAP_NET_RAW (not running as root)")
    if not _have_libpcap():
        pytest.skip("--bpf needs libpcap (scripts/install-test-tools.sh installs it with tshark)")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sink:
        sink.bind(("127.0.0.1", 0))
        port = sink.getsockname()[1]
        pcap = tmp_path / "sniff.pcap"
        out, err = io.StringIO(), io.StringIO()
        result: list[int] = []
        t = threading.Thread(target=lambda: result.append(main(
            ["live", "--sniff", "lo", "--bpf", f"udp dst port {port}", "-T", "jsonl", "-c", "3", "-w", str(pcap),
             "--duration", "10"], Env(stdout=out, stderr=err))), daemon=True)
        t.start()
        deadline = time.monotonic() + 10
        while "sniffing on lo" not in err.getvalue() and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.2)
        mav = pmav.mav2(100, 1)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.sendto(b"not mavlink", ("127.0.0.1", port + 1 if port < 65535 else port - 1))  # filtered out
            for i in range(3):
                s.sendto(pmav.statustext(mav, f"sniffed {i}"), ("127.0.0.1", port))
        t.join(15)
    assert result == [ExitStatus.OK], err.getvalue()
    frames = _frames_of(out.getvalue())
    assert [f["fields"]["text"] for f in frames] == ["sniffed 0", "sniffed 1", "sniffed 2"]  # once each on lo
    assert all(f["dst"] == f"127.0.0.1:{port}" for f in frames)
    rows = _tshark_fields(pcap, "udp.dstport")
    assert rows == [[str(port)]] * 3


def test_bpf_without_libpcap_is_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    import scapy.arch  # noqa: F401 - sets conf.L2listen
    from scapy.config import conf

    def no_libpcap(**kwargs: object) -> None:
        raise ImportError("libpcap is not available. Cannot compile filter !")  # what scapy raises

    monkeypatch.setattr(conf, "L2listen", no_libpcap)
    code, out, err = _run_cli("live", "--sniff", "lo", "--bpf", "udp", "--duration", "1")
    assert code == ExitStatus.ERROR and out == ""
    assert err.strip().count("\n") == 0 and "--bpf needs libpcap" in err and "apt-get install libpcap0.8" in err


def test_sniff_without_privilege_is_one_line() -> None:
    cmd = [sys.executable, "-m", "mavscope", "live", "--sniff", "lo", "--duration", "1"]
    if os.geteuid() == 0:
        setpriv = shutil.which("setpriv")
        if setpriv is None:
            pytest.skip("running as root and setpriv is absent: cannot drop the privilege to test its absence")
        # stay root (the checkout may be readable by root only) but without CAP_NET_RAW
        cmd = [setpriv, "--bounding-set=-net_raw", "--inh-caps=-net_raw", *cmd]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60, cwd=ROOT, check=False)
    if proc.returncode == 0:
        pytest.skip("this user may capture (CAP_NET_RAW granted)")
    assert proc.returncode == ExitStatus.ERROR
    assert proc.stderr == "mavscope: live --sniff needs root or CAP_NET_RAW\n"


def test_reader_going_away_ends_quietly() -> None:
    """`mavscope live ... | head -1`: the pipe closes, mavscope stops with its summary and status 0."""
    proc = subprocess.Popen([sys.executable, "-m", "mavscope", "live", "--udp", "127.0.0.1:0", "-T", "jsonl",
                             "--duration", "10"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    try:
        assert proc.stderr is not None and proc.stdout is not None
        m = LISTENING.search(proc.stderr.readline().decode())
        assert m
        port = int(m.group(2))
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.sendto(pmav.heartbeat(pmav.mav2(1, 1)), ("127.0.0.1", port))
            assert json.loads(proc.stdout.readline())["sysid"] == 1
            proc.stdout.close()
            for _ in range(20):
                s.sendto(pmav.heartbeat(pmav.mav2(1, 1)), ("127.0.0.1", port))
                time.sleep(0.01)
        err = proc.stderr.read().decode()
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert SUMMARY.match(err.splitlines()[-1]) and "Traceback" not in err


def test_signature_verdicts_live() -> None:
    """--key works live: the capture time (the kernel's receive time) is the receiver clock for new streams."""
    from tests.support.security import SHA_KEY, signer

    now = int((time.time() - 1_420_070_400) * 100_000)
    good = signer(SHA_KEY, sysid=1, compid=1, timestamp=now)
    forged = signer(bytes(32), sysid=2, compid=1, timestamp=now)
    run = LiveRun("--udp", "127.0.0.1:0", "-T", "jsonl", "--key", f"hex:{SHA_KEY.hex()}", "-c", "2", "--duration", "8")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(pmav.heartbeat(good), ("127.0.0.1", run.port))
        s.sendto(pmav.heartbeat(forged), ("127.0.0.1", run.port))
    status, out, _ = run.join()
    assert status == ExitStatus.OK
    frames = _frames_of(out)
    assert [f["signature"]["status"] for f in frames] == ["valid", "invalid"]  # type: ignore[index]


def test_time_formats_and_colour_live() -> None:
    """`live -t e --color=always`: the read options on live lines (a summary line's time column as epoch
    seconds: the datagram's receive time, so within the test's clock; a bad-CRC frame in red, the TUI's
    RED as 24-bit SGR, a good one uncoloured)."""
    before = time.time()
    run = LiveRun("--udp", "127.0.0.1:0", "-t", "e", "--color=always", "-c", "2", "--duration", "8")
    vehicle = pmav.mav2(1, 1)
    bad = bytearray(pmav.heartbeat(vehicle))
    bad[-3] ^= 0x55
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(pmav.heartbeat(vehicle), ("127.0.0.1", run.port))
        s.sendto(bytes(bad), ("127.0.0.1", run.port))
    status, out, _ = run.join()
    assert status == ExitStatus.OK
    good, red = out.splitlines()[:2]
    assert "\x1b" not in good and red.startswith("\x1b[1;38;2;255;95;95m") and red.endswith("\x1b[0m")
    epoch = float(good.split()[1])
    assert before - 1 <= epoch <= time.time() + 1
