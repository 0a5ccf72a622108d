"""No key given to export, sql or batch ends up in the dataset, the CSV, or on stdout and stderr (the
key names do: `signature_key`). Keys and secrets are those of tests/security/test_no_secret_printed.py."""

from __future__ import annotations

from pathlib import Path

import pyarrow.parquet as pq

from tests.conftest import CAPTURES, Cli
from tests.security.test_no_secret_printed import KEYS, RING_KEY, SECRETS

PATHS = [CAPTURES / n for n in ("signed_udp.pcap", "securemav_udp.pcap", "key_exchange_udp.pcap")]


def _clean(where: str, text: str) -> None:
    for s in SECRETS:
        assert s not in text, f"a secret in {where}"


def test_keys_stay_out_of_datasets_and_output(cli: Cli, tmp_path: Path) -> None:
    ring = tmp_path / "ring.toml"
    ring.write_text(f'[keys]\nfleet = "hex:{RING_KEY}"\n')
    ring.chmod(0o600)
    env = {"MAVSCOPE_KEYRING": str(ring)}
    root = tmp_path / "ds"
    runs = [
        ("export", *map(str, PATHS), "--parquet", str(root), *KEYS),
        ("export", *map(str, PATHS), "-T", "csv", "-o", str(tmp_path / "csv"), *KEYS),
        ("sql", "SELECT signature_key, count(*) FROM frames GROUP BY 1", *map(str, PATHS), "--json", *KEYS),
        ("batch", *map(str, PATHS), "--json", "--", "verify", *KEYS),
        ("batch", *map(str, PATHS), "--", "audit", *KEYS),
    ]
    for argv in runs:
        status, out, err = cli(*argv, environ=env)
        assert status in (0, 1), (argv[0], err)
        _clean(f"{argv[0]} stdout", out)
        _clean(f"{argv[0]} stderr", err)
    names = set()
    for f in root.rglob("*.parquet"):
        table = pq.read_table(f)
        _clean(f"{f} metadata", repr(table.schema.metadata) + repr([c.metadata for c in table.schema]))
        for col in table.columns:
            for v in col.to_pylist():
                if isinstance(v, bytes):
                    _clean(str(f), v.hex())
                    _clean(str(f), v.decode("latin-1"))
                elif v is not None:
                    _clean(str(f), str(v))
        if "signature_key" in table.column_names:
            names.update(table.column("signature_key").to_pylist())
    assert "key1" in names  # the name of the key that verified (the first --key has none of its own)
    for f in (tmp_path / "csv").rglob("*.csv"):
        _clean(str(f), f.read_text())
