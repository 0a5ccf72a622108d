"""A passphrase that is not UTF-8 on the command line (defect 13, key part).

A Latin-1 terminal hands `passphrase:café` over as the bytes 63 61 66 e9; Python decodes argv with
surrogate escapes ('caf\\udce9') and `passphrase_key` raised UnicodeEncodeError. The key is now the
SHA-256 of the original bytes (os.fsencode), as MAVProxy computes it on that terminal.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

from mavscope.errors import UsageError
from mavscope.security.keys import QGC_ITERATIONS, QGC_SALT, build_material, passphrase_key, qgc_key
from tests.support.builders import write_udp_pcap
from tests.support.security import heartbeat, signer

LATIN1 = b"caf\xe9 cr\xe8me"  # not UTF-8
SHA = hashlib.sha256(LATIN1).digest()
FSENC_UTF8 = sys.getfilesystemencoding().lower().replace("-", "") == "utf8"


@pytest.mark.skipif(not FSENC_UTF8, reason="argv decodes with surrogate escapes only under a UTF-8 locale")
def test_a_latin1_passphrase_keys_from_its_bytes() -> None:
    text = os.fsdecode(LATIN1)  # what sys.argv holds
    assert "\udce9" in text
    assert passphrase_key(text) == SHA
    material = build_material([f"passphrase:{text}"], [f"2=xor:passphrase:{text}"])
    assert material.signing[0].secret == SHA and material.ciphers[2].key == SHA
    assert qgc_key(text) == hashlib.pbkdf2_hmac("sha256", LATIN1, QGC_SALT, QGC_ITERATIONS, 32)


def test_utf8_passphrases_are_unchanged() -> None:
    assert passphrase_key("mavscope-démo") == hashlib.sha256("mavscope-démo".encode()).digest()
    assert passphrase_key("mavscope-demo") == hashlib.sha256(b"mavscope-demo").digest()


def test_a_lone_surrogate_is_a_usage_error_not_a_crash() -> None:
    with pytest.raises(UsageError) as exc:
        passphrase_key("x\ud800y")
    assert "\ud800" not in str(exc.value)


@pytest.mark.skipif(not FSENC_UTF8, reason="argv decodes with surrogate escapes only under a UTF-8 locale")
def test_verify_with_a_latin1_passphrase_on_the_command_line(tmp_path: Path) -> None:
    """The real entry point, the argument passed as bytes: the frame signed with SHA-256(bytes) verifies."""
    datagram = (("10.0.0.1", 14550), ("10.0.0.2", 14540), heartbeat(signer(SHA)))
    path = write_udp_pcap(tmp_path / "signed.pcap", [datagram], t0=1_773_482_400.0)
    exe = Path(sys.executable).with_name("mavscope")
    env = {**os.environ, "LC_ALL": "C.UTF-8", "PYTHONUTF8": "1"}
    proc = subprocess.run([exe, "verify", str(path).encode(), b"--key", b"passphrase:" + LATIN1],
                          capture_output=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    # (the table's columns shrink with the temporary path's length: its last line says it)
    assert b"Traceback" not in proc.stderr and proc.stdout.endswith(b"OK: every signed frame verified\n")
