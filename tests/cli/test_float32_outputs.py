"""Every output shows a float32 field as the shortest text that reads back as the same float32 (issue 35
item 15), on both engines alike: summary lines, the detail tree (`read -V`), JSON Lines, `params` (and its
.param file), `commands`.

The capture is built with pymavlink; the expected texts are derived by hand in tests/mavlink/test_floats.py
(30.48: the float32 30.479999542236328 lies 4.6e-7 from it, within its half step 9.5e-7; 12.2036295 needs
its 9 digits; 2**-149 reads 1e-45; FLT_MAX 3.4028235e+38; 2**24 + 1 rounds to 16777216; 2**90 1.2379401e+27).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from tests.support.flows import T0, Sender, heartbeat, write_tlog

ENGINES = [{}, {"MAVSCOPE_PURE": "1"}]


def capture(tmp: Path) -> str:
    vehicle, gcs = Sender(1, 1), Sender(255, 190)
    return write_tlog(tmp, [
        (T0, vehicle.pack(heartbeat())),
        (T0 + 0.1, vehicle.pack(v2.MAVLink_param_value_message(b"RTL_ALT", 30.48, 9, 1, 0))),
        (T0 + 0.2, vehicle.pack(v2.MAVLink_attitude_message(1000, 12.203629493713379, 1.401298464324817e-45,
                                                           3.4028234663852886e38, -0.0, 16777217.0, 2.0**90))),
        (T0 + 0.3, gcs.pack(v2.MAVLink_command_long_message(1, 1, 22, 0, 0, 0, 0, 0, 0, 0, 30.48))),
    ])


def test_read_outputs(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    path = capture(tmp_path)
    for args in ([], ["-V"], ["-T", "jsonl"]):
        native, pure = (cli("read", path, *args, environ=e) for e in ENGINES)
        assert native == pure, args  # stdout, stderr and status alike
    lines = cli("read", path).out.splitlines()
    assert lines[1].endswith("PARAM_VALUE param_id='RTL_ALT' param_value=30.48 param_index=0")
    assert lines[2].endswith("ATTITUDE roll=12.2036295 pitch=1e-45 yaw=3.4028235e+38")
    tree = cli("read", path, "-V").out
    for text in ("param_value: 30.48", "roll: 12.2036295 rad", "pitch: 1e-45 rad", "yaw: 3.4028235e+38 rad",
                 "rollspeed: -0.0 rad/s", "pitchspeed: 16777216.0 rad/s", "yawspeed: 1.2379401e+27 rad/s",
                 "Altitude (param7): 30.48 m"):
        assert text in tree, text
    jsonl = cli("read", path, "-T", "jsonl").out
    assert '"param_value":30.48,' in jsonl and '"param7":30.48,' in jsonl
    assert ('"roll":12.2036295,"pitch":1e-45,"yaw":3.4028235e+38,"rollspeed":-0.0,"pitchspeed":16777216.0,'
            '"yawspeed":1.2379401e+27}') in jsonl
    frames = [json.loads(line) for line in jsonl.splitlines()]
    assert frames[1]["fields"]["param_value"] == 30.48


@pytest.mark.parametrize("engine", ENGINES, ids=["native", "pure"])
def test_params_and_commands(cli, tmp_path: Path, engine: dict[str, str]) -> None:  # type: ignore[no-untyped-def]
    path = capture(tmp_path)
    out = tmp_path / "x.param"
    status, _, err = cli("params", path, "--out", str(out), environ=engine)
    assert status == 0, err
    assert "RTL_ALT,30.48" in out.read_text().splitlines()
    assert cli.json("params", path, environ=engine)  # (its values: analysis/params json_value, the same helper)
    commands = cli("commands", path, environ=engine).out
    assert "Altitude 30.48" in commands and "30.4799995" not in commands
