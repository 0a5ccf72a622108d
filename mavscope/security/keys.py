"""Key material: `--key`, `--cipher`, `--ecdh-private` specs and TOML keyrings (docs/security.md).

A secret is held by a `SigningKey` or `CipherKey` whose `repr` shows only its name; every error
message names the option and what is wrong with its shape, never the value: a refused spec is described
by the length of its pieces (`_shape`), never by any character of what may be the key. A key's NAME is
echoed only once it is known to be a NAME (followed by `=` and a spec of a known kind).
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import os
import re
import stat
import tomllib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

from mavscope.errors import UsageError
from mavscope.transport.wpa import WifiKey, wifi_key

QGC_SALT = b"QGroundControl-MAVLink-Signing-v1"
QGC_ITERATIONS = 600_000
KEY_LEN = 32
KEYRING_ENV = "MAVSCOPE_KEYRING"
SCHEMES = ("xor", "aes-128-ctr", "aes-gcm")
SECUREMAV_TEST_METHOD = 7  # SecureMAV's test cipher: every payload byte XOR 0xAB
SECUREMAV_TEST_XOR = b"\xab"
AES_GCM_DEFAULT_METHOD = 6  # method used for keys from the key exchange unless --cipher says otherwise


def passphrase_bytes(text: str) -> bytes:
    """The bytes a passphrase was typed as: `os.fsencode`, so that a command-line argument that is not
    UTF-8 (a Latin-1 terminal; Python hands it over with surrogate escapes) gives back its original
    bytes, as the program the user typed it into would use them. Text that is UTF-8 gives its UTF-8."""
    try:
        return os.fsencode(text)
    except UnicodeEncodeError:  # a lone surrogate that no byte decodes to (not from a command line)
        raise UsageError("a passphrase holds a character that cannot be encoded") from None


def passphrase_key(text: str) -> bytes:
    """SHA-256 of the passphrase's bytes (MAVProxy, older QGroundControl)."""
    return hashlib.sha256(passphrase_bytes(text)).digest()


def qgc_key(text: str) -> bytes:
    """PBKDF2-HMAC-SHA256, QGroundControl's salt, 600000 iterations (current QGroundControl)."""
    return hashlib.pbkdf2_hmac("sha256", passphrase_bytes(text), QGC_SALT, QGC_ITERATIONS, KEY_LEN)


class SigningKey:
    """A 32-byte MAVLink signing secret with a name. Prints as its name only."""

    __slots__ = ("name", "_secret", "_hash")

    def __init__(self, name: str, secret: bytes) -> None:
        if len(secret) != KEY_LEN:
            raise UsageError(f"key {name}: a signing key is {KEY_LEN} bytes, not {len(secret)}")
        self.name = name
        self._secret = bytes(secret)
        self._hash = hashlib.sha256(self._secret)  # copied per frame: the key block is hashed once

    @property
    def secret(self) -> bytes:
        return self._secret

    def mac(self, data: bytes) -> bytes:
        """First 6 bytes of SHA-256(secret || data)."""
        h = self._hash.copy()
        h.update(data)
        return h.digest()[:6]

    def __repr__(self) -> str:
        return f"SigningKey({self.name!r})"

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        return isinstance(other, SigningKey) and other._secret == self._secret

    def __hash__(self) -> int:
        return hash(self._secret)


@dataclass(frozen=True)
class CipherKey:
    """The cipher configured for one SecureMAV method number. Prints without its key."""

    method: int
    scheme: str
    key: bytes = field(repr=False)  # empty for `ecdh` (keys come from the key exchange)
    iv: bytes = field(default=b"\x00" * 16, repr=False)
    from_ecdh: bool = False


@dataclass
class KeyMaterial:
    """Everything the security stage may use. Empty material still gives the key-free verdicts."""

    signing: list[SigningKey] = field(default_factory=list)
    ciphers: dict[int, CipherKey] = field(default_factory=dict)
    ecdh_private: list[bytes] = field(default_factory=list, repr=False)
    use_leaked_keys: bool = False
    wifi: tuple[WifiKey, ...] = ()  # WPA2 networks' keys (--wifi-key), for the transport layer's 802.11

    def __repr__(self) -> str:
        return (f"KeyMaterial(signing={[k.name for k in self.signing]}, ciphers={sorted(self.ciphers)}, "
                f"ecdh_private={len(self.ecdh_private)}, use_leaked_keys={self.use_leaked_keys}, "
                f"wifi={len(self.wifi)})")

    @property
    def has_signing_material(self) -> bool:
        return bool(self.signing or self.ecdh_private or self.use_leaked_keys)


_NAME = re.compile(r"^[A-Za-z0-9_.@-]{1,64}$")
_KINDS = ("hex:", "base64:", "passphrase:", "qgc:", "file:")
_EXPECTED = "expected hex:, base64:, passphrase:, qgc: or file: before the key"


def _shape(text: str) -> str:
    """What a refused piece of a key spec looks like, without any of its characters."""
    return "nothing" if not text else "1 character" if len(text) == 1 else f"{len(text)} characters"


def _split_name(spec: str) -> tuple[str | None, str]:
    """`NAME=SPEC` -> (NAME, SPEC); a SPEC alone -> (None, SPEC).

    A NAME holds no ':' and is followed by a spec of a known kind: anything else may be a key written
    without its kind (base64 ends in '='), so it stays the SPEC and is never shown as a NAME.
    """
    head, sep, tail = spec.partition("=")
    if sep and ":" not in head and head and tail.startswith(_KINDS):
        if not _NAME.match(head):
            raise UsageError("--key: a key NAME is 1-64 letters, digits, '_', '.', '@' or '-'")
        return head, tail
    return None, spec


def _decode_bytes(kind: str, value: str, what: str) -> bytes:
    if kind == "hex":
        value = value.strip()
        if not re.fullmatch(r"[0-9A-Fa-f]*", value) or len(value) % 2:
            raise UsageError(f"{what}: hex: needs an even number of hex digits")
        return bytes.fromhex(value)
    if kind == "base64":
        try:
            return base64.b64decode(value.strip(), validate=True)
        except (binascii.Error, ValueError):
            raise UsageError(f"{what}: base64: is not valid base64") from None
    raise UsageError(f"{what}: unknown key kind ({_shape(kind)} before ':')")


def secret_from_spec(spec: str, what: str) -> bytes:
    """The 32-byte secret of `hex:`, `base64:`, `passphrase:` or `qgc:` (not `file:`)."""
    kind, sep, value = spec.partition(":")
    if not sep:
        raise UsageError(f"{what}: {_EXPECTED} (got {_shape(spec)} without ':')")
    if kind == "passphrase":
        return passphrase_key(value)
    if kind == "qgc":
        return qgc_key(value)
    if kind in ("hex", "base64"):
        secret = _decode_bytes(kind, value, what)
        if len(secret) != KEY_LEN:
            digits = " (64 hex digits)" if kind == "hex" else ""
            raise UsageError(f"{what}: {kind}: a signing key is {KEY_LEN} bytes{digits}, got {len(secret)}")
        return secret
    raise UsageError(f"{what}: unknown key kind ({_shape(kind)} before ':'); {_EXPECTED}")


def cipher_from_spec(spec: str, what: str = "--cipher") -> CipherKey:
    """`METHOD=SCHEME:KEYSPEC[:iv=HEX]`; for `xor` KEYSPEC may be omitted for method 7 (0xAB)."""
    method_text, sep, rest = spec.partition("=")
    digits = method_text.strip(" \t")
    if not sep or not (digits.isascii() and digits.isdigit()):  # int() takes neither '²' nor '\x1d'
        raise UsageError(f"{what}: expected METHOD=SCHEME:KEYSPEC, METHOD 1..7")
    method = int(digits)
    if not 1 <= method <= 7:
        got = digits if len(digits) <= 3 else f"a number of {len(digits)} digits"
        raise UsageError(f"{what}: METHOD is 1..7 (incompat flag bits 5-7), not {got}")
    iv = b"\x00" * 16
    m = re.search(r":iv=([0-9A-Fa-f]*)$", rest)
    if m:
        rest = rest[: m.start()]
        if len(m.group(1)) != 32:
            raise UsageError(f"{what}: iv= takes 32 hex digits (16 bytes)")
        iv = bytes.fromhex(m.group(1))
    scheme, _, keyspec = rest.partition(":")
    if scheme not in SCHEMES:
        raise UsageError(f"{what}: unknown scheme ({_shape(scheme)} after METHOD=); "
                         "expected METHOD=SCHEME:KEYSPEC with SCHEME xor, aes-128-ctr or aes-gcm")
    if scheme == "aes-gcm" and keyspec == "ecdh":
        return CipherKey(method, scheme, b"", iv, from_ecdh=True)
    if not keyspec:
        if scheme == "xor" and method == SECUREMAV_TEST_METHOD:
            return CipherKey(method, scheme, SECUREMAV_TEST_XOR, iv)
        raise UsageError(f"{what}: method {method}: {scheme} needs a key (hex:, base64:, passphrase:)")
    kind, _, value = keyspec.partition(":")
    if kind == "passphrase":
        key = passphrase_key(value)
    elif kind in ("hex", "base64"):
        key = _decode_bytes(kind, value, f"{what}: method {method}")
    else:
        raise UsageError(f"{what}: method {method}: unknown key kind ({_shape(kind)} after the scheme); "
                         "expected hex:, base64: or passphrase: before the key")
    if scheme == "xor" and not key:
        raise UsageError(f"{what}: method {method}: xor needs at least one key byte")
    if scheme == "aes-128-ctr" and len(key) != 16:
        raise UsageError(f"{what}: method {method}: aes-128-ctr needs a 16-byte key, got {len(key)} bytes")
    if scheme == "aes-gcm" and len(key) not in (16, 32):
        raise UsageError(f"{what}: method {method}: aes-gcm needs a 16- or 32-byte master key, got {len(key)}")
    return CipherKey(method, scheme, key, iv)


def ecdh_private_from_spec(spec: str, what: str = "--ecdh-private") -> bytes:
    kind, sep, value = spec.partition(":")
    if not sep or kind not in ("hex", "base64"):
        raise UsageError(f"{what}: expected hex:<64 hex digits> or base64:<...>")
    raw = _decode_bytes(kind, value, what)
    if len(raw) != 32:
        raise UsageError(f"{what}: an X25519 private key is 32 bytes, got {len(raw)}")
    return raw


def load_keyring(path: str, material: KeyMaterial, warn: Callable[[str], object]) -> None:
    """Add the keys, ciphers and ECDH private keys of a TOML keyring to `material`."""
    try:
        st = os.stat(path)
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except OSError as exc:
        raise UsageError(f"keyring {path}: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        # the decoder's message gives line and column, never the line's text
        raise UsageError(f"keyring {path}: not valid TOML ({str(exc).split('(')[-1].rstrip(')')})") from None
    except ValueError:  # a NUL byte in the path: os.stat refuses it
        raise UsageError(f"keyring {path!r}: not a usable file name") from None
    if st.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        warn(f"warning: keyring {path} is readable by group or others (chmod 600 {path})")
    keys = data.get("keys", {})
    if not isinstance(keys, dict):
        raise UsageError(f"keyring {path}: [keys] must be a table of NAME = \"SPEC\"")
    for i, (name, spec) in enumerate(keys.items(), 1):
        if not isinstance(spec, str) or not _NAME.match(name):
            # the name is not shown: a key pasted where the name goes is still a key
            raise UsageError(f"keyring {path}: entry {i} of [keys]: expected NAME = \"hex:...\" (or base64:, "
                             "passphrase:, qgc:), NAME 1-64 letters, digits, '_', '.', '@' or '-'")
        material.signing.append(SigningKey(name, secret_from_spec(spec, f"keyring {path}: key {name}")))
    ciphers = data.get("ciphers", [])
    if not isinstance(ciphers, list) or not all(isinstance(c, str) for c in ciphers):
        raise UsageError(f"keyring {path}: ciphers must be a list of \"METHOD=SCHEME:KEYSPEC\" strings")
    for c in ciphers:
        cipher = cipher_from_spec(c, f"keyring {path}: cipher")
        material.ciphers[cipher.method] = cipher
    ecdh = data.get("ecdh_private", [])
    if isinstance(ecdh, str):
        ecdh = [ecdh]
    if not isinstance(ecdh, list) or not all(isinstance(e, str) for e in ecdh):
        raise UsageError(f"keyring {path}: ecdh_private must be \"hex:...\" or a list of them")
    for e in ecdh:
        material.ecdh_private.append(ecdh_private_from_spec(e, f"keyring {path}: ecdh_private"))


def build_material(keys: Iterable[str] = (), ciphers: Iterable[str] = (), ecdh_private: Iterable[str] = (),
                   *, use_leaked_keys: bool = False, environ: Mapping[str, str] | None = None,
                   warn: Callable[[str], object] = lambda _m: None, wifi: Iterable[str] = ()) -> KeyMaterial:
    """Key material from command-line specs (and the keyring `MAVSCOPE_KEYRING` names, first)."""
    material = KeyMaterial(use_leaked_keys=use_leaked_keys,
                           wifi=tuple(wifi_key(spec, i) for i, spec in enumerate(wifi, 1)))
    default_ring = (environ or {}).get(KEYRING_ENV)
    if default_ring:
        load_keyring(default_ring, material, warn)
    unnamed = 0
    for spec in keys:
        name, body = _split_name(spec)
        if body.startswith("file:"):
            if name is not None:
                raise UsageError("--key: a keyring (file:) names its own keys; drop NAME=")
            load_keyring(body[5:], material, warn)
            continue
        if name is None:
            unnamed += 1
            name = f"key{unnamed}"
        what = f"--key {name}"
        material.signing.append(SigningKey(name, secret_from_spec(body, what)))
    for spec in ciphers:
        cipher = cipher_from_spec(spec)
        material.ciphers[cipher.method] = cipher
    for spec in ecdh_private:
        material.ecdh_private.append(ecdh_private_from_spec(spec))
    names = [k.name for k in material.signing]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise UsageError(f"--key: key name(s) given twice: {', '.join(sorted(dup))}")
    return material
