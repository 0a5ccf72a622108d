"""Key material out of error messages: what a user typed after a key option, or that looks like a key
spec, is never echoed back.

argparse quotes what it did not understand (`unrecognized arguments: --kee passphrase:SECRET`,
`ambiguous option: --k=hex:...`, `invalid choice: ...`), and a command's own usage errors may quote a
value. `redact(text, argv)` replaces, in any such text, every word of `argv` that is secret-bearing:

- a value given to an option that is, or looks like a misspelling of, an option that takes key material
  (`--key`, `--cipher`, `--ecdh-private`, `--wifi-key`, `--keyring`...; `--kee`, `--wifikey`, `-key`);
- a word that holds a key spec's kind anywhere (`hex:`, `base64:`, `passphrase:`, `qgc:`, `wpa-pwd:`,
  `wpa-psk:`, and the cipher schemes), whatever option it was given to, or none.

The secret part is replaced too where it appears on its own (`passphrase:SECRET` -> also `SECRET`), so a
message that quotes only the value leaks nothing either.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Sequence

REDACTED = "<redacted>"

# The options whose values are key material (commands/common.add_key_options, the keyring, the audit's
# wordlist is a file name: not secret).
SECRET_OPTIONS: tuple[str, ...] = ("--key", "--cipher", "--ecdh-private", "--wifi-key", "--keyring", "--psk",
                                   "--passphrase", "--secret")
_SPEC = re.compile(r"(?i)(?:hex|base64|passphrase|qgc|wpa-pwd|wpa-psk|aes-128-ctr|aes-gcm|xor|x25519)\s*[:=]")
_MIN_SECRET = 3  # shorter fragments ("ab") are not replaced on their own: they would blank ordinary words


def _secret_option(option: str) -> bool:
    """`option` (with its dashes) takes key material, or is a near-miss of one that does."""
    name = option.split("=", 1)[0].lower()
    if not name.startswith("-"):
        return False
    bare = "--" + name.lstrip("-")
    if any(word in bare for word in ("key", "cipher", "secret", "pass", "psk", "pwd", "ecdh")):
        return True
    # a near-miss of a long option (`--kee`, `--cpher`); a one-letter option (`-Y`, `-c`) is no near-miss
    return len(bare) >= 5 and any(difflib.SequenceMatcher(None, bare, o).ratio() >= 0.75 for o in SECRET_OPTIONS)


def secret_words(argv: Sequence[str]) -> list[str]:
    """The words of `argv`, and parts of them, that must never be shown, longest first."""
    found: set[str] = set()
    follows_secret = False
    for word in argv:
        if word == "--":
            follows_secret = False
            continue
        option, eq, value = word.partition("=")
        if follows_secret and not (word.startswith("--") and len(word) > 2):
            found.add(word)
        follows_secret = False
        if word.startswith("-") and len(word) > 1 and _secret_option(option):
            if eq:
                found.add(value)
            else:
                follows_secret = True
        if _SPEC.search(word):
            found.add(word)
    parts: set[str] = set()
    for word in found:
        # NAME=kind:SECRET, kind:SECRET, METHOD=scheme:kind:SECRET:iv=HEX: every piece after a kind counts
        for m in _SPEC.finditer(word):
            parts.add(word[m.end():])
        if "=" in word:
            parts.add(word.split("=", 1)[1])
    found |= {p for p in parts if len(p) >= _MIN_SECRET}
    return sorted((w for w in found if w), key=len, reverse=True)


def redact(text: str, argv: Sequence[str]) -> str:
    """`text` with every secret-bearing word of `argv` (secret_words) replaced by REDACTED."""
    for word in secret_words(argv):
        if len(word) >= _MIN_SECRET or word in text.split():
            text = text.replace(word, REDACTED)
    return text
