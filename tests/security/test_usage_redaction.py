"""Key material typed on the command line never comes back in a usage error (issue 35, item 8).

The class: every usage error of every command, whatever argparse or a command quotes. The secrets below
are marker strings chosen here; a leak is the marker appearing anywhere in stdout or stderr. Each case is
a way a user really mistypes: a misspelt option (`--kee`, `--wifikey`), an abbreviation that argparse finds
ambiguous, a key given as a stray positional, a key spec given to an option that takes something else, a
value after `=`; on several commands, since each builds its own parser.
"""

from __future__ import annotations

import pytest

from mavscope.security.redact import REDACTED, redact, secret_words
from tests.conftest import CAPTURES, Cli

PCAP = str(CAPTURES / "px4_sitl_udp.pcap")
S = "Zq7SECRETmarker"  # appears in no capture, option name or message of mavscope

CASES = [
    ("read", PCAP, "--kee", f"passphrase:{S}"),
    ("read", PCAP, "--kee", S),
    ("read", PCAP, f"--kee=passphrase:{S}"),
    ("read", PCAP, "--wifikey", f"wpa-pwd:{S}:net"),
    ("read", PCAP, f"--wifi-kee=wpa-psk:{S}"),
    ("read", PCAP, "--ciper", f"1=aes-128-ctr:hex:{S}"),
    ("read", PCAP, f"hex:{S}"),
    ("read", PCAP, "-c", f"passphrase:{S}"),
    ("stats", PCAP, "--kee", f"qgc:{S}"),
    ("verify", PCAP, "--kee", f"base64:{S}"),
    ("audit", PCAP, "--ecdh-privat", f"hex:{S}"),
    ("export", PCAP, "--kee", f"passphrase:{S}"),
    ("read", PCAP, "--key", f"bogus:{S}"),
    ("read", PCAP, "--key", f"name=passphrase:{S}", "--bogus"),
    ("batch", str(CAPTURES), "--", "verify", "--kee", f"passphrase:{S}"),
]


@pytest.mark.parametrize("argv", CASES, ids=lambda a: " ".join(a[2:])[:40])
def test_no_usage_error_echoes_a_key(cli: Cli, argv: tuple[str, ...]) -> None:
    status, out, err = cli(*argv)
    assert S not in out and S not in err, (out, err)
    # still a usage error, and still one that names what went wrong (the option, not the value)
    if status == 2:
        assert err.startswith("mavscope: ")


def test_the_redaction_keeps_what_is_not_a_key() -> None:
    # The file name and the misspelt option stay: they are what the user has to fix.
    text = f"unrecognized arguments: --kee passphrase:{S} extra.pcap"
    argv = ["read", "x.pcap", "--kee", f"passphrase:{S}", "extra.pcap"]
    assert redact(text, argv) == f"unrecognized arguments: --kee {REDACTED} extra.pcap"
    # a value after an option that takes no key is left alone unless it looks like a key spec
    assert secret_words(["-c", "25", "-Y", "HEARTBEAT"]) == []
    assert secret_words(["-Y", f"hex:{S}"]) == [f"hex:{S}", S]
