#!/usr/bin/env python3
"""Every analysis command on six hostile tlogs: time and peak memory per command, to show both stay
bounded by the input (docs/security.md, "Bounded time and memory per byte").

    benchmarks/hostile_matrix.py [--frames N] [--out DIR] [--commands NAME,...]

The tlogs (N frames each, 200,000 by default; pymavlink packs the frames, seeded): every frame from a
random one of the 65,025 senders with a random sequence number, and
- params: PARAM_VALUEs and PARAM_SETs of random names, values, indexes and targets;
- statustext: STATUSTEXTs of random text, chunk id and chunk number;
- heartbeat_flap: HEARTBEATs of 255 systems switching type, autopilot, armed state and mode each frame;
- gps_spray: GLOBAL_POSITION_INTs at random places;
- mission_items: MISSION_ITEM_INTs of random seq, mission type and target, with no MISSION_COUNT;
- commands: COMMAND_LONGs and COMMAND_ACKs of random commands, results and targets.
Each command runs in a fresh process (`/usr/bin/time`), stdout to /dev/null; the table is printed as
Markdown.
"""

from __future__ import annotations

import argparse
import os
import random
import struct
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from pymavlink.dialects.v20 import all as v2

T0 = 1_773_482_400.0
COMMANDS = ["stats --json", "events --json", "params --json", "commands --json", "mission --json", "objects --json",
            "track --json", "timeline --json", "audit --json", "read -T jsonl", "export --parquet {ds}"]


def _tlogs(n: int, out: Path) -> list[Path]:
    rnd = random.Random(11)
    mavs: dict[tuple[int, int], v2.MAVLink] = {}

    def name(k: int = 16) -> bytes:
        return bytes(rnd.choice(b"ABCDEFGHIJKLMNOPQRSTUVWXYZ_0123456789") for _ in range(rnd.randrange(1, k + 1)))

    def u(bits: int) -> int:
        return rnd.randrange(1 << bits)

    def i32() -> int:
        return rnd.randrange(-(1 << 31), 1 << 31)

    kinds: dict[str, Callable[[int], object]] = {
        "params": lambda i: v2.MAVLink_param_value_message(name(), rnd.random() * 1e6, rnd.randrange(1, 10), u(16),
                                                           u(16)) if i % 2 else
        v2.MAVLink_param_set_message(u(8), u(8), name(), rnd.random(), 9),
        "statustext": lambda i: v2.MAVLink_statustext_message(u(3), bytes(rnd.randrange(32, 127) for _ in range(50)),
                                                              u(16), u(8)),
        "heartbeat_flap": lambda i: v2.MAVLink_heartbeat_message(rnd.choice([1, 2, 6, 10]), rnd.choice([3, 12, 8]),
                                                                 rnd.choice([0, 128, 209]), u(32), u(3), 3),
        "gps_spray": lambda i: v2.MAVLink_global_position_int_message(u(32), rnd.randrange(-900000000, 900000000),
                                                                      rnd.randrange(-1800000000, 1800000000), i32(),
                                                                      i32(), 0, 0, 0, u(16)),
        "mission_items": lambda i: v2.MAVLink_mission_item_int_message(u(8), u(8), u(16), rnd.randrange(20), u(16), 0,
                                                                       1, 0, 0, 0, 0, i32(), i32(), 0, u(8)),
        "commands": lambda i: v2.MAVLink_command_long_message(u(8), u(8), u(16), u(8), *[rnd.random()] * 7)
        if i % 2 else v2.MAVLink_command_ack_message(u(16), u(8), u(8), i32(), u(8), u(8)),
    }
    paths = []
    for kind, make in kinds.items():
        path = out / f"{kind}_{n}.tlog"
        paths.append(path)
        if path.exists():
            continue
        buf = bytearray()
        for i in range(n):
            sender = (rnd.randrange(1, 256), 1 if kind == "heartbeat_flap" else rnd.randrange(1, 256))
            mav = mavs.setdefault(sender, v2.MAVLink(None, srcSystem=sender[0], srcComponent=sender[1]))
            mav.seq = u(8)
            buf += struct.pack(">Q", int((T0 + i * 0.001) * 1e6)) + bytes(make(i).pack(mav))  # type: ignore[attr-defined]
        path.write_bytes(buf)
    return paths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200_000)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "out")
    ap.add_argument("--commands", help="only these commands (their first words, comma-separated: stats,export)")
    args = ap.parse_args()
    commands = COMMANDS if not args.commands else [c for c in COMMANDS if c.split()[0] in args.commands.split(",")]
    args.out.mkdir(parents=True, exist_ok=True)
    mavscope = str(Path(sys.executable).parent / "mavscope")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    print("| capture | MB | " + " | ".join(f"`{c.split()[0]}`" for c in commands) + " |")
    print("|---|---:|" + "---:|" * len(commands))
    for path in _tlogs(args.frames, args.out):
        cells = []
        for command in commands:
            with tempfile.TemporaryDirectory() as tmp:
                words = command.format(ds=Path(tmp) / "ds").split()
                timing = Path(tmp) / "time"
                run = subprocess.run(["/usr/bin/time", "-f", "%e %M", "-o", str(timing), mavscope, words[0],
                                      str(path), *words[1:]], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                     env=env, check=False)
                seconds, kb = timing.read_text().split()[-2:]
                bad = "" if run.returncode == 0 else f" rc {run.returncode}"
                cells.append(f"{float(seconds):.1f} s, {int(kb) // 1024} MB{bad}")
        print(f"| {path.stem} | {path.stat().st_size / 1e6:.1f} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
