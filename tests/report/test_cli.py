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

from mavscope.native.core import available
from tests.conftest import CAPTURES, ROOT, Cli

KEY = ("--key", "vehicle=passphrase:mavscope-demo")  # captures/README.md: signed_udp.pcap's passphrase
SCHEMA = json.loads((ROOT / "docs" / "report.schema.json").read_text())
BUNDLED = sorted(p.name for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))
FINDING_KEYS = ("code", "severity", "frames", "message", "rule", "offset")


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
