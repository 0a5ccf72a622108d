"""Secrets never appear in error messages (defect 5) or on screen in the key dialog.

A typo in a key spec used to echo the key: `--cipher 2=aes-128-ctr:<hex without hex:>` printed
"unknown key kind '<the AES key>'", a bare base64 `--key` ending in '=' was split as NAME= and printed,
`--key 'Secret:x'` printed `Secret`, and keyring entries did the same. A refused spec is now described
by its shape only. A key's NAME is not secret once it is known to be one (`NAME=hex:...`).
"""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from mavscope.cli import Env, main
from mavscope.errors import MavscopeError
from mavscope.security.keys import build_material
from tests.support.tui import CAPTURES, SIZE, ready, run, type_text

MARK = "S3cr3tMarkerQz"  # a passphrase-like secret
HEX = "7C852089FFDB16126DBEE7C968A751B5"  # SecureMAV's AES test key
B64 = "QUJDREVGR0hJSktMTU5PUFFSU1RVVldYWVphYmNkZWY="  # a bare base64 key, '=' at the end
SECRETS = (MARK, HEX, B64.rstrip("="))

KEY_SPECS = [
    *SECRETS, B64, B64 + "=", MARK + "=", MARK + ":x", f"{HEX}:{MARK}", f"name={MARK}", f"name={HEX}",
    f"name={MARK}:x", f"name={B64}", f"hex:{MARK}", f"hex:{HEX}", f"base64:{MARK}!", f"base64:{HEX}",
    f"hex{MARK}", f"file{MARK}", f"{MARK}+/x=hex:00", f"=={MARK}", f"Hex:{HEX}", f" hex:{HEX}", f"{MARK} :x",
]
CIPHER_SPECS = [
    f"2=aes-128-ctr:{HEX}", f"2=xor:{MARK}", f"2={MARK}", f"2={HEX}", f"2={MARK}:hex:00", f"{MARK}=xor",
    f"2=aes-gcm:{MARK}:iv=00", f"2=aes-128-ctr:hex:{MARK}", f"2=aes-128-ctr:hex:{HEX}00", f"2=xor:base64:{MARK}",
    f"2=aes-128-ctr:{MARK}:iv={HEX}", f"7{HEX}=xor", f"2=aes-gcm:passphrase:{MARK}:iv=1", f"2:{MARK}",
    f"12345678901234567890{HEX[:8]}=xor", f"2=AES-128-CTR:hex:{HEX}", f"2=xor:{B64}",
]
ECDH_SPECS = [MARK, HEX, f"hex:{MARK}", f"base64:{MARK}", f"hex:{HEX}", f"{MARK}:{HEX}", f"file:{MARK}"]


def assert_secret_free(text: str) -> None:
    for secret in SECRETS:
        for form in (secret, secret.lower(), secret[:12], secret[-12:]):
            assert form not in text, text


def refused(**options: list[str]) -> str:
    with pytest.raises(MavscopeError) as exc:
        build_material(options.get("keys", ()), options.get("ciphers", ()), options.get("ecdh", ()))
    return str(exc.value)


@pytest.mark.parametrize("spec", KEY_SPECS)
def test_a_refused_key_spec_is_described_by_its_shape(spec: str) -> None:
    assert_secret_free(refused(keys=[spec]))


@pytest.mark.parametrize("spec", CIPHER_SPECS)
def test_a_refused_cipher_spec_is_described_by_its_shape(spec: str) -> None:
    assert_secret_free(refused(ciphers=[spec]))


@pytest.mark.parametrize("spec", ECDH_SPECS)
def test_a_refused_ecdh_private_key_is_described_by_its_shape(spec: str) -> None:
    assert_secret_free(refused(ecdh=[spec]))


def test_the_messages_still_say_what_is_wrong() -> None:
    assert "unknown key kind (32 characters after the scheme)" in refused(ciphers=[f"2=aes-128-ctr:{HEX}"])
    assert "44 characters without ':'" in refused(keys=[B64])
    assert "unknown key kind (14 characters before ':')" in refused(keys=[f"{MARK}:x"])
    assert "unknown scheme (14 characters after METHOD=)" in refused(ciphers=[f"2={MARK}:hex:00"])
    assert "not a number of 28 digits" in refused(ciphers=["1234567890123456789012345678=xor"])
    assert "not 9" in refused(ciphers=["9=xor"])
    assert refused(keys=["lab-key=hex:00"]).startswith("--key lab-key: ")  # a NAME is no secret


KEYRINGS = [
    f'[keys]\n"{MARK}!" = "hex:00"\n', f'[keys]\n"{HEX} x" = "passphrase:x"\n', f'[keys]\nname = "{MARK}"\n',
    f'[keys]\nname = "{MARK}:x"\n', f'[keys]\nname = "{B64}"\n', f'[keys]\nname = "hex:{HEX}"\n',
    f'ciphers = ["2=xor:{MARK}"]\n', f'ciphers = ["2={HEX}"]\n', f'ecdh_private = "{MARK}"\n',
    f'ecdh_private = ["hex:{HEX}"]\n', f'[keys]\n"{B64}" = 5\n', f'[keys]\nname = "{MARK}\n',
    f'keys = "{MARK}"\n', f'ciphers = "{MARK}"\n',
]


@pytest.mark.parametrize("content", KEYRINGS)
def test_keyring_entries_are_described_by_their_shape(tmp_path: Path, content: str) -> None:
    ring = tmp_path / "ring.toml"
    ring.write_text(content)
    ring.chmod(0o600)
    assert_secret_free(refused(keys=[f"file:{ring}"]))
    with pytest.raises(MavscopeError) as exc:
        build_material(environ={"MAVSCOPE_KEYRING": str(ring)})
    assert_secret_free(str(exc.value))


@pytest.mark.parametrize(("option", "spec"), [("--key", B64), ("--key", f"{MARK}:x"),
                                              ("--cipher", f"2=aes-128-ctr:{HEX}"), ("--cipher", f"2=xor:{MARK}"),
                                              ("--ecdh-private", HEX)])
def test_the_command_line_prints_no_secret(option: str, spec: str) -> None:
    out, err = io.StringIO(), io.StringIO()
    status = main(["read", str(CAPTURES / "signed_udp.pcap"), "-c", "1", option, spec],
                  Env(stdout=out, stderr=err, environ={}))
    assert status == 2 and err.getvalue().startswith("mavscope: ")
    assert_secret_free(out.getvalue() + err.getvalue())


def test_the_key_dialog_masks_what_is_typed_and_its_error() -> None:
    from textual.widgets import Input, Static

    from mavscope.tui.app import create_app
    from mavscope.tui.screens.keys import KeyDialog, redact

    assert redact(f"bad {MARK} and {HEX}", f"x={MARK}:{HEX}") == "bad ••• and •••"
    assert redact("--key key1: hex: 32 bytes", "hex:00") == "--key key1: hex: 32 bytes"

    async def scenario() -> None:
        app = create_app(CAPTURES / "signed_udp.pcap")
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("k")
            dialog = app.screen
            assert isinstance(dialog, KeyDialog)
            field = dialog.query_one("#key-input", Input)
            assert field.password
            await pilot.click("#kind-4", offset=(6, 0))  # a cipher spec, as --cipher
            await pilot.click("#key-input")
            await type_text(pilot, f"2=xor:{MARK}")
            assert MARK not in str(field.render())
            await pilot.press("enter")
            await pilot.pause()
            assert app.screen is dialog
            error = str(dialog.query_one("#key-error", Static).render())
            assert "unknown key kind" in error
            assert_secret_free(error)
            await pilot.press("escape")

    run(scenario())


def test_a_keyring_path_with_a_nul_byte_is_a_usage_error() -> None:
    """Found by `make fuzz` (keys target): os.stat raised ValueError on a NUL byte in a file: path."""
    with pytest.raises(MavscopeError, match="not a usable file name"):
        build_material(["file:/tmp/a\0b.toml"])
