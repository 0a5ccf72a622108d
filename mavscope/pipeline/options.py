"""PipelineOptions: everything a front end may ask of the pipeline, as one frozen value.

The command line turns its arguments into options once (`commands/common.py`); the TUI changes
them with `dataclasses.replace` (adding a key is `replace(options, keys=options.keys + (spec,))`);
live capture, the benchmarks and library users build them directly. Key specs stay text here
("hex:...", "passphrase:..."): the security layer parses them when a session is built, and their
repr hides them so that no traceback or log line shows a key.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class PipelineOptions:
    """What the pipeline runs: dialects to load, key material, and the display filter."""

    dialects: tuple[str, ...] = ()  # extra dialect XML files (dissectors/*.xml load by themselves)
    keys: tuple[str, ...] = field(default=(), repr=False)  # --key [NAME=]SPEC
    ciphers: tuple[str, ...] = field(default=(), repr=False)  # --cipher METHOD=SCHEME:KEYSPEC
    ecdh_private: tuple[str, ...] = field(default=(), repr=False)  # --ecdh-private hex:KEY
    use_leaked_keys: bool = False  # verify the frames after a SETUP_SIGNING with the key it leaks
    keyring: str | None = None  # a default TOML keyring ($MAVSCOPE_KEYRING), loaded before `keys`
    wifi_keys: tuple[str, ...] = field(default=(), repr=False)  # --wifi-key wpa-pwd:PASSPHRASE:SSID | wpa-psk:HEX
    display_filter: str | None = None  # -Y: which frames are shown

    @property
    def has_key_material(self) -> bool:
        """Whether any key was given that can verify signatures (ciphers alone cannot)."""
        return bool(self.keys or self.ecdh_private or self.use_leaked_keys or self.keyring)
