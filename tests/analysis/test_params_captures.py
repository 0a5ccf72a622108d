"""`mavscope params` on the bundled parameter captures, against the truth files the generator wrote from what
it sent (captures/<capture>.truth.json); the exported `.param` read back by pymavlink's own loader
(`mavparm.MAVParmDict.load`, what MAVProxy's `param load` uses), the `.params` by QGroundControl's format."""

from __future__ import annotations

import json
import struct
from pathlib import Path

from pymavlink.mavparm import MAVParmDict

from tests.conftest import CAPTURES, Cli

KEY = ("--key", "passphrase:mavscope-demo")  # the generator signs the GCS's frames with it (captures/README.md)


def truth(capture: str) -> dict:
    return json.loads((CAPTURES / capture.replace(".pcap", ".truth.json")).read_text())


def f32(v: float) -> bytes:
    return struct.pack("<f", v)


def same(a: float, b: float) -> bool:
    return f32(a) == f32(b)


def test_final_values_and_timeline(cli: Cli) -> None:
    t = truth("ftp_params.pcap")["params"]
    doc = cli.json("params", CAPTURES / "ftp_params.pcap", *KEY)
    assert doc["main_component"] == t["main_component"]
    assert sorted(doc["final"]) == sorted(t["final"])
    assert all(same(doc["final"][n], v) for n, v in t["final"].items())
    camera = next(c for c in doc["components"] if [c["sysid"], c["compid"]] == [1, 100])
    assert {n: p["value"] for n, p in camera["parameters"].items()} == t["camera_final"]
    main = next(c for c in doc["components"] if [c["sysid"], c["compid"]] == t["main_component"])
    assert {n: p["type_id"] for n, p in main["parameters"].items()} == t["types"]
    assert (main["count"], main["announced_count"], main["encoding"]) == (t["count"], t["count"], "c-cast")
    got = [(e["kind"], e["name"], e["from"], e["component"], e["confirmed"], e["retries"], e["security"],
            e["disables"], e["signature"]) for e in doc["timeline"]]
    want = [(e["kind"], e["name"], e["from"], e["component"], e["confirmed"], e["retries"], e["security"],
             e["disables"], "valid" if e["signed"] else "unsigned") for e in t["timeline"]]
    assert got == want
    for g, w in zip(doc["timeline"], t["timeline"], strict=True):
        assert same(g["value"], w["value"]) and same(g["previous"], w["previous"])
        if w["reported"] is not None:
            assert same(g["reported"], w["reported"])
    ftp = doc["ftp"]
    objects = truth("ftp_params.pcap")["objects"]
    assert [(x["sha256"], x["decoded"], x["problems"]) for x in ftp] == [(o["sha256"], t["count"], []) for o in objects]
    codes = sorted((f["code"], f["frames"][0]) for f in doc["findings"])
    flagged = [e for e in doc["timeline"] if e["security"]]
    assert codes == sorted(("param-protection-disabled" if e["disables"] else "param-security-change", e["frame"])
                           for e in flagged)


def test_export_param_and_params(cli: Cli, tmp_path: Path) -> None:
    t = truth("ftp_params.pcap")["params"]
    out = tmp_path / "vehicle.param"
    status, _, err = cli("params", CAPTURES / "ftp_params.pcap", "--out", out)
    assert status == 0, err
    loaded = MAVParmDict()
    # pymavlink's loader, as `param load` in MAVProxy (which by default skips FORMAT_VERSION and a few others)
    assert loaded.load(str(out), mav=None, use_excludes=False)
    assert sorted(loaded) == sorted(t["final"])
    assert all(same(loaded[n], v) for n, v in t["final"].items())
    assert out.read_text().splitlines()[2].split(",")[0] == sorted(t["final"])[0]  # NAME,VALUE sorted by name

    out = tmp_path / "vehicle.params"
    status, _, err = cli("params", CAPTURES / "ftp_params.pcap", "--out", out)
    assert status == 0, err
    lines = out.read_text().splitlines()
    assert lines[0] == "# Onboard parameters for Vehicle 1"
    assert "# Vehicle-Id Component-Id Name Value Type" in lines
    rows = [line.split("\t") for line in lines if not line.startswith("#")]
    assert all(len(r) == 5 for r in rows)
    main = {r[2]: (float(r[3]), int(r[4])) for r in rows if r[:2] == ["1", "1"]}
    camera = {r[2]: (float(r[3]), int(r[4])) for r in rows if r[:2] == ["1", "100"]}
    assert sorted(main) == sorted(t["final"]) and all(same(main[n][0], v) for n, v in t["final"].items())
    assert {n: v[1] for n, v in main.items()} == t["types"]
    assert camera == {"CAM_EV": (0.5, 9), "CAM_MODE": (2.0, 1)}  # MAV_PARAM_EXT_TYPE_REAL32, _UINT8


def test_diff_against_a_parameter_file_and_a_capture(cli: Cli, tmp_path: Path) -> None:
    t = truth("ftp_params.pcap")["params"]
    before = tmp_path / "before.param"
    before.write_text("# the parameters as first read\n" +
                      "".join(f"{n} {v}\n" for n, v in t["initial"].items()))  # MAVProxy's spelling
    doc = cli.json("params", CAPTURES / "ftp_params.pcap", "--diff", before)
    d = doc["diff"]
    changed = sorted(n for n in t["final"] if not same(t["final"][n], t["initial"][n]))
    assert sorted(d["changed"]) == changed and d["only_here"] == {} and d["only_there"] == {}
    assert d["other_kind"] == "parameter file"
    assert d["security"] == {"ARMING_CHECK": "arming checks", "MAV1_OPTIONS": "signing and access",
                             "SCR_ENABLE": "scripting"}
    assert set(d["disables"]) == {"ARMING_CHECK", "MAV1_OPTIONS"}
    doc = cli.json("params", CAPTURES / "ftp_params.pcap", "--diff", CAPTURES / "ftp_params.pcap")
    assert doc["diff"]["changed"] == {} and doc["diff"]["other_kind"] == "capture"


def test_parameters_set_by_writing_param_pck(cli: Cli) -> None:
    t = truth("ftp_lua_upload.pcap")["params"]["timeline"]
    doc = cli.json("params", CAPTURES / "ftp_lua_upload.pcap")
    assert [(e["kind"], e["name"], e["value"], e["from"], e["component"], e["source"], e["confirmed"])
            for e in doc["timeline"]] == [(e["kind"], e["name"], e["value"], e["from"], e["component"], e["source"],
                                           e["confirmed"]) for e in t]
    assert [x["direction"] for x in doc["ftp"]] == ["upload"]
    assert sorted(f["code"] for f in doc["findings"]) == ["param-protection-disabled", "param-security-change"]


def test_text_output(cli: Cli) -> None:
    status, out, err = cli("params", CAPTURES / "ftp_params.pcap")
    assert status == 0, err
    assert "Component 1/1: 162 parameters (announced 162)" in out
    assert "[error] param-protection-disabled" in out and "ARMING_CHECK !" in out
