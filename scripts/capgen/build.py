"""`make_all`: every capture, then expected.json and README.md. The order is fixed because
expected.json and the README list the captures in it, and the tlog and the serial dump reuse the frames
of the UDP session."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .analysis import clock_skew, commands_ack, mission_resend, stats_loss
from .basic import mavlink_v1_udp, px4_sitl_sll2, px4_sitl_tlog, px4_sitl_udp, serial_dump, signed_udp
from .damaged import damaged
from .incidents import gcs_takeover, gps_spoof
from .objects import ftp_lua_upload, ftp_params, log_download
from .readme import (
    render_analysis_truth,
    render_incidents,
    render_objects_truth,
    render_readme,
    render_security_captures,
)
from .security import key_exchange_udp, securemav_udp
from .summary import dump_expected
from .tcp import px4_sitl_tcp


def make_all(outdir: Path) -> dict[str, Any]:
    """Write every capture, expected.json and README.md into outdir; return the expected results."""
    outdir.mkdir(parents=True, exist_ok=True)
    expected: dict[str, Any] = {}
    expected["px4_sitl_udp.pcap"], udp_sends = px4_sitl_udp(outdir)
    expected["px4_sitl_tcp.pcap"] = px4_sitl_tcp(outdir)
    expected["mavlink_v1_udp.pcap"] = mavlink_v1_udp(outdir)
    expected["signed_udp.pcap"] = signed_udp(outdir)
    expected["damaged.pcap"], cases = damaged(outdir)
    expected["damaged.pcap"]["cases"] = [[c.record, c.what, c.expect] for c in cases]
    expected["px4_sitl.tlog"] = px4_sitl_tlog(outdir, udp_sends)
    expected["serial_dump.raw"] = serial_dump(outdir, udp_sends)
    expected["px4_sitl_sll2.pcapng"] = px4_sitl_sll2(outdir)
    expected["stats_loss.pcap"] = stats_loss(outdir)
    expected["mission_resend.pcap"] = mission_resend(outdir)
    expected["commands_ack.pcap"] = commands_ack(outdir)
    expected["clock_skew.pcap"] = clock_skew(outdir)
    expected["securemav_udp.pcap"] = securemav_udp(outdir)
    expected["key_exchange_udp.pcap"] = key_exchange_udp(outdir)
    expected["ftp_params.pcap"] = ftp_params(outdir)
    expected["ftp_lua_upload.pcap"] = ftp_lua_upload(outdir)
    expected["log_download.pcap"] = log_download(outdir)
    expected["gcs_takeover.pcap"] = gcs_takeover(outdir)
    expected["gps_spoof.pcap"] = gps_spoof(outdir)
    (outdir / "expected.json").write_text(dump_expected(expected), encoding="utf-8")
    (outdir / "README.md").write_text(render_readme(expected, cases) + render_analysis_truth(expected)
                                      + render_security_captures(expected) + render_objects_truth(expected)
                                      + render_incidents(outdir),
                                      encoding="utf-8")
    return expected
