"""No secret is printed: every command, given key material, over every bundled capture; and the TUI.

The secrets are the user's: the passphrase and the key derived from it, a cipher key, an X25519
private key, given on the command line and in a keyring. None may appear in stdout, stderr, the JSON,
a file written with -w or --plan, or on the TUI's screen. (A key a capture carries in clear, in
SETUP_SIGNING, is the capture's data, shown as the frame's bytes and reported as a leak; and `audit
--wordlist` prints the passphrase it found on purpose: neither is tested here.)
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from mavscope.tui.app import create_app
from tests.conftest import CAPTURES, Cli
from tests.support.tui import SIZE, ready, run, type_text, wait_for

PASSPHRASE = "mavscope-demo"
SIGNING_KEY = hashlib.sha256(PASSPHRASE.encode()).hexdigest()
CIPHER_KEY = "7c852089ffdb16126dbee7c968a751b5"
ECDH_KEY = "3fd8e0bc8bc5bab654bbe4c04d4f780293dc14b287ad8ce5cb496342442c04b3"
RING_KEY = "5e" * 32
SECRETS = (PASSPHRASE, SIGNING_KEY, SIGNING_KEY.upper(), CIPHER_KEY, CIPHER_KEY.upper(), ECDH_KEY, RING_KEY)
KEYS = ("--key", f"passphrase:{PASSPHRASE}", "--key", f"vehicle=hex:{SIGNING_KEY}",
        "--cipher", f"2=aes-128-ctr:hex:{CIPHER_KEY}", "--ecdh-private", f"hex:{ECDH_KEY}")
ALL = sorted(p for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))
COMMANDS = (
    ("read",), ("read", "-V", "-x"), ("read", "-T", "jsonl"), ("stats", "--json"), ("stats",),
    ("mission", "--json"), ("commands", "--json"), ("timeline", "--json"), ("verify", "--json"), ("verify",),
    ("audit", "--json"), ("audit",), ("params", "--json"), ("events", "--json"),
    ("track", "--gpx", "-"), ("plot", "mavlink.seq", "--json"),
)


def _clean(where: str, text: str) -> None:
    for s in SECRETS:
        assert s not in text, f"a secret in {where}"


@pytest.mark.parametrize("path", ALL, ids=lambda p: p.name)
def test_every_command_keeps_the_keys_to_itself(cli: Cli, path: Path, tmp_path: Path) -> None:
    ring = tmp_path / "ring.toml"
    ring.write_text(f'[keys]\nfleet = "hex:{RING_KEY}"\n')
    ring.chmod(0o600)
    env = {"MAVSCOPE_KEYRING": str(ring)}
    for command in COMMANDS:
        status, out, err = cli(command[0], str(path), *command[1:], *KEYS, environ=env)
        assert status in (0, 1), (command, err)
        _clean(f"{command} stdout", out)
        _clean(f"{command} stderr", err)
    out_file = tmp_path / "out.pcapng"
    status, _, err = cli("read", str(path), *KEYS, "-w", str(out_file), "-q", environ=env)
    assert status == 0, err
    _clean("-w output", out_file.read_bytes().hex())
    _clean("-w output", out_file.read_bytes().decode("latin-1"))
    objects = tmp_path / "objects"
    status, out, err = cli("objects", str(path), *KEYS, "--out", str(objects), "--json", environ=env)
    assert status == 0, err
    _clean("objects stdout", out)
    _clean("objects stderr", err)
    for written in objects.iterdir():
        _clean(f"objects --out {written.name}", written.read_bytes().decode("latin-1"))


def test_refused_specs_and_keyring_errors_do_not_echo_the_key(cli: Cli, tmp_path: Path) -> None:
    for spec in ([f"--key={SIGNING_KEY}"], [f"--key=hex:{SIGNING_KEY[:-2]}"], [f"--cipher=2=aes-128-ctr:{CIPHER_KEY}"],
                 [f"--cipher=2=xor:{PASSPHRASE}"], [f"--ecdh-private={ECDH_KEY}"]):
        status, out, err = cli("read", str(CAPTURES / "signed_udp.pcap"), *spec)
        assert status == 2 and err.count("\n") == 1, (spec, err)
        _clean(f"{spec} error", out + err)
    ring = tmp_path / "bad.toml"
    ring.write_text(f'[keys]\nfleet = "{SIGNING_KEY}"\n')
    status, out, err = cli("verify", str(CAPTURES / "signed_udp.pcap"), "--key", f"file:{ring}")
    assert status == 2
    _clean("keyring error", out + err)


def test_the_tui_shows_no_key() -> None:
    """Keys from the command line and one typed into the `k` dialog (masked as it is typed): the screen
    shows the number of keys and their verdicts, never a key."""
    from mavscope.commands.tui import parse_options
    from mavscope.tui.screens.keys import KeyDialog

    path = CAPTURES / "signed_udp.pcap"
    screens: list[str] = []

    async def scenario() -> None:
        app = create_app(path, parse_options([str(path), "--cipher", f"2=aes-128-ctr:hex:{CIPHER_KEY}"]))
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("k")
            assert isinstance(app.screen, KeyDialog)
            await type_text(pilot, PASSPHRASE)
            screens.append(app.export_screenshot())  # the dialog, with the passphrase typed
            await pilot.press("enter")
            await wait_for(pilot, lambda: app.pending is None and app.index.done, timeout=60)
            screens.append(app.export_screenshot())

    run(scenario())
    for n, svg in enumerate(screens):
        _clean(f"TUI screen {n}", svg)
