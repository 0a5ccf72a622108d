"""`mavscope report` against the commands whose answers it shows, on bundled captures: its findings are
`audit --json`'s, its figures `stats --json`'s, its events `events --json`'s, its plots `plot --json`'s, its
map `track --geojson`'s,
with the same key options (the report runs each analysis the way that command does: they must agree). The
document validates against docs/report.schema.json; two runs differ only in the time of the analysis."""

from __future__ import annotations

import json
import re
from pathlib import Path

import jsonschema
import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.analysis.events import FIRST_KEPT, LAST_KEPT
from mavscope.native.core import available
from tests.conftest import CAPTURES, ROOT, Cli
from tests.support.builders import heartbeat_msg
from tests.support.flows import command_long
from tests.support.ftpflows import GCS, VEHICLE, Flow

KEY = ("--key", "vehicle=passphrase:mavscope-demo")  # captures/README.md: signed_udp.pcap's passphrase
SCHEMA = json.loads((ROOT / "docs" / "report.schema.json").read_text())
BUNDLED = sorted(p.name for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))
FINDING_KEYS = ("code", "severity", "frames", "message", "rule", "offset")
MAX_PAGE = 5 * 1024 * 1024


def _report(cli: Cli, tmp: Path, *argv: str) -> tuple[dict, str]:
    html, js = tmp / "r.html", tmp / "r.json"
    status, out, err = cli("report", *argv, "-o", str(html), "--json", str(js))
    assert status == 0, err
    assert out == ""  # (the report's line goes to stderr)
    return json.loads(js.read_text()), html.read_text(encoding="utf-8")


def _agrees(cli: Cli, tmp: Path, path: Path, *keys: str) -> None:
    doc, _ = _report(cli, tmp, str(path), *keys)
    jsonschema.validate(doc, SCHEMA)
    (one,) = doc["inputs"]
    audit = cli("audit", str(path), *keys, "--json")
    assert audit.status in (0, 1), audit.err
    want = json.loads(audit.out)
    assert [{k: f[k] for k in FINDING_KEYS if k in f} for f in one["findings"]] == want["findings"]
    assert one["frames"] == want["frames"]
    stats = cli.json("stats", str(path), *keys)
    assert one["stats"] == {k: stats[k] for k in ("messages", "links", "conversations", "totals")}
    events = cli.json("events", str(path), *keys)
    assert [{k: v for k, v in e.items() if k != "show"} for e in one["events"]["events"]] == events["events"]
    assert (one["events"]["counts"], one["events"]["dropped"]) == (events["counts"], events["dropped"])
    exprs = [p["field"] for p in one["plots"]]
    plot = cli.json("plot", str(path), *exprs, *keys)
    for mine, theirs in zip(one["plots"], plot["series"], strict=True):
        assert mine["field"] == theirs["field"]
        assert (mine["count"], mine["min"], mine["max"], mine["interval"]) == (
            theirs["count"], theirs["min"], theirs["max"], theirs["interval"])
        assert mine["buckets"] == [[b["start"], b["min"], b["max"]] for b in theirs["buckets"]]
    geo = tmp / "t.geojson"
    assert cli("track", str(path), *keys, "--geojson", str(geo)).status == 0
    assert one["map"] == json.loads(geo.read_text())


@pytest.mark.parametrize("name", BUNDLED)
def test_the_report_agrees_with_the_commands(cli: Cli, tmp_path: Path, name: str) -> None:
    _agrees(cli, tmp_path, CAPTURES / name)


def test_with_the_key_the_findings_are_audits_with_it(cli: Cli, tmp_path: Path) -> None:
    _agrees(cli, tmp_path, CAPTURES / "signed_udp.pcap", *KEY)
    doc, html = _report(cli, tmp_path, str(CAPTURES / "signed_udp.pcap"), *KEY)
    assert doc["custody"]["keys"]["--key"] == ["vehicle"]
    assert "mavscope-demo" not in json.dumps(doc) and "mavscope-demo" not in html  # the secret never appears
    assert doc["custody"]["command_line"][-2:] == ["--key", "vehicle"]
    sig = {(s["sysid"], s["compid"]): s["signature"] for s in doc["inputs"][0]["summary"]["signing"]}
    assert set(sig[(1, 1)]) == {"valid"}  # every frame signed and verified (captures/README.md)


def test_the_same_inputs_give_the_same_report(cli: Cli, tmp_path: Path) -> None:
    a_doc, a_html = _report(cli, tmp_path, str(CAPTURES / "gps_spoof.pcap"), str(CAPTURES / "mission_resend.pcap"))
    b_doc, b_html = _report(cli, tmp_path, str(CAPTURES / "gps_spoof.pcap"), str(CAPTURES / "mission_resend.pcap"))
    stamp = a_doc["custody"].pop("analysed_at"), b_doc["custody"].pop("analysed_at")
    assert a_doc == b_doc
    assert a_html.replace(stamp[0], "T") == b_html.replace(stamp[1], "T")
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", stamp[0])
    assert [i["file"]["name"] for i in a_doc["inputs"]] == ["gps_spoof.pcap", "mission_resend.pcap"]


def test_usage_errors(cli: Cli, tmp_path: Path) -> None:
    cap = CAPTURES / "gps_spoof.pcap"
    status, _, err = cli("report", str(cap))
    assert status == 2 and "-o" in err
    status, _, err = cli("report", str(cap), "-o", str(cap))
    assert status == 2 and "capture being read" in err
    bad = tmp_path / "bad.param"
    bad.write_bytes(b"\xff\xfe not text")
    status, _, err = cli("report", str(cap), "-o", str(tmp_path / "r.html"), "--params-file", str(bad))
    assert status == 2 and "--params-file" in err
    assert not (tmp_path / "r.html").exists()


def test_no_secret_in_the_page_or_the_json(cli: Cli, tmp_path: Path) -> None:
    """Every kind of key option and a keyring ($MAVSCOPE_KEYRING): the page, the JSON and the streams name
    the keys (and the keyring's path), never a secret, in any case (tests/security/test_no_secret_printed's
    secrets and key options)."""
    from tests.security.test_no_secret_printed import KEYS as ALL_KEYS
    from tests.security.test_no_secret_printed import RING_KEY, SECRETS

    ring = tmp_path / "ring.toml"
    ring.write_text(f'[keys]\nfleet = "hex:{RING_KEY}"\n')
    ring.chmod(0o600)
    html, js = tmp_path / "r.html", tmp_path / "r.json"
    status, out, err = cli("report", str(CAPTURES / "signed_udp.pcap"), *ALL_KEYS, "-o", str(html), "--json", str(js),
                           environ={"MAVSCOPE_KEYRING": str(ring)})
    assert status == 0, err
    written = html.read_text(encoding="utf-8") + js.read_text(encoding="utf-8") + out + err
    for secret in SECRETS:
        assert secret not in written and secret.lower() not in written.lower()
    custody = json.loads(js.read_text())["custody"]
    assert custody["keys"] == {"--key": ["(passphrase, unnamed)", "vehicle"], "--cipher": ["2"],
                               "--ecdh-private": ["(hex, unnamed)"], "--wifi-key": []}
    assert custody["keyring"] == str(ring)


@pytest.mark.skipif(not available({}), reason="the C extension is not built: only the pure engine runs")
def test_both_engines_give_the_same_report(tmp_path: Path) -> None:
    """The native walker's batches and the Python pipeline's (MAVSCOPE_PURE=1) give the same document but for
    the engine named and the time (the analyses are the same Python over either, docs/architecture.md)."""
    docs = []
    for environ in ({}, {"MAVSCOPE_PURE": "1"}):
        out = tmp_path / f"r{len(docs)}.json"
        status, _, err = Cli(environ)("report", str(CAPTURES / "signed_udp.pcap"), *KEY, "-o", str(tmp_path / "r.html"),
                                      "--json", str(out))
        assert status == 0, err
        docs.append(json.loads(out.read_text()))
    engines = [d["inputs"][0].pop("engine") for d in docs]
    for d in docs:
        d["custody"].pop("analysed_at")
        d["custody"].pop("command_line")
    assert engines == ["native", "pure-python"]
    assert docs[0] == docs[1]


def test_a_long_capture_makes_a_short_page(cli: Cli, tmp_path: Path) -> None:
    """A capture with far more rows than the page shows: the page stays small (well under 5 MB), says how
    many rows it left out and names the command that lists them all, and the JSON keeps every one the
    analyses keep. Built here: 12,000 STATUSTEXTs, 3,000 parameter values, 3,000 commands, 2,000 positions."""
    flow = Flow()
    flow.send(VEHICLE, heartbeat_msg(2, 3, 1, 0, 3))
    flow.send(GCS, heartbeat_msg(6, 8))
    for i in range(12_000):
        flow.send(VEHICLE, v2.MAVLink_statustext_message(6, f"text {i} <b>&".encode()), dt=0.001)
        if i % 4 == 0:
            flow.send(VEHICLE, v2.MAVLink_param_value_message(b"SOME_PARAM", float(i), 9, 1, 0), dt=0.001)
            flow.send(GCS, command_long(511, float(i)), dt=0.001)
        if i % 6 == 0:
            flow.send(VEHICLE, v2.MAVLink_global_position_int_message(i, 473_977_420 + i, 85_455_940, 500_000, i,
                                                                       0, 0, 0, 0), dt=0.001)
    cap = flow.write(tmp_path, "long.tlog")
    status, _, err = cli("report", str(cap), "-o", str(tmp_path / "r.html"), "--json", str(tmp_path / "r.json"))
    assert status == 0, err
    page = (tmp_path / "r.html").read_text(encoding="utf-8")
    doc = json.loads((tmp_path / "r.json").read_text())
    assert len(page.encode()) < MAX_PAGE
    story = doc["inputs"][0]["events"]
    events = story["events"]
    # the JSON has every one the story keeps (its bound: the first and the last of each kind and sender) and
    # counts all 12,000
    assert len([e for e in events if e["kind"] == "statustext"]) == FIRST_KEPT + LAST_KEPT
    assert story["counts"]["statustext"] == 12_000 and story["dropped"]["statustext"] == 12_000 - FIRST_KEPT - LAST_KEPT
    assert "7000 statustext events were not listed" in page
    assert page.count('<tr class="ev-') == 400  # the page the first 400...
    assert f"{len(events) - 400} more events: <code>mavscope events {cap} --json</code> lists them all" in page
    changes = doc["inputs"][0]["params"]["changes"]
    assert len(changes) == 2_999  # one PARAM_VALUE in four of the texts: the first its value, each later one a change
    assert f"{len(changes) - 300} more: <code>mavscope params {cap} --json</code>" in page


def test_a_flood_of_senders_is_cut_and_said(cli: Cli, tmp_path: Path) -> None:
    """150 made-up vehicles (a HEARTBEAT and two positions each, sysid 1..150): the page lists the first 100
    vehicles and tracks and says 50 more of each, and draws the 20 tracks of the most positions (all have
    two: the first 20), saying 130 left out; the JSON keeps all 150."""
    flow = Flow()
    for n in range(1, 151):
        flow.send((n, 1), heartbeat_msg(10, 3, 1, 0, 4))
        for k in (0, 1):
            flow.send((n, 1), v2.MAVLink_global_position_int_message(k, 473_977_420 + n * 100, 85_455_940 + k * 100,
                                                                      500_000, 0, 0, 0, 0, 0))
    cap = flow.write(tmp_path, "flood.tlog")
    doc, page = _report(cli, tmp_path, str(cap))
    one = doc["inputs"][0]
    assert len(one["summary"]["vehicles"]) == 150
    assert sum(1 for f in one["map"]["features"] if f["properties"]["kind"] == "track") == 150
    assert "50 more\nvehicles" in page and "50 more tracks" in page
    assert "130 track features not drawn" in page
    svg = re.search(r'<svg[^>]*id="mapsvg-1">(.*?)</svg>', page, re.S)
    assert svg is not None and svg.group(1).count("<polyline class=\"track") == 20
