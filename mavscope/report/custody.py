"""Chain of custody: what the report was made from and how, stated before anything it concludes.

Each input's name, size and SHA-256 (read from the file itself, in 1 MiB blocks), mavscope's version, the
engine each capture was read with, every dialect file loaded with its SHA-256, the names of the keys given
(never a secret: a key spec prints as its name or its kind, mavscope.security.keys), the command line and
when the analysis ran. Only `analysed_at` differs between two runs over the same inputs.
"""

from __future__ import annotations

import datetime
import hashlib
import os
import platform
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from mavscope import __version__
from mavscope.errors import UsageError
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.dialect_cache import cache_dir, record_of
from mavscope.mavlink.dialect_check import MAX_FILES, include_path
from mavscope.rules.loader import pack_files
from mavscope.rules.loader import rule_files as rule_files_of

BLOCK = 1 << 20


@dataclass(frozen=True, slots=True)
class FileHash:
    path: str  # as given on the command line
    name: str  # its base name
    size: int
    sha256: str

    def to_json(self) -> dict[str, object]:
        return {"path": self.path, "name": self.name, "size": self.size, "sha256": self.sha256}


def file_hash(path: str) -> FileHash:
    """The size and SHA-256 of the file at `path` (UsageError when it cannot be read)."""
    digest = hashlib.sha256()
    size = 0
    try:
        with open(path, "rb") as fh:
            while block := fh.read(BLOCK):
                digest.update(block)
                size += len(block)
    except OSError as exc:
        raise UsageError(f"report: {path}: {exc.strerror or exc}") from None
    return FileHash(path, os.path.basename(path), size, digest.hexdigest())


def dialect_files(dialect: Dialect) -> list[dict[str, object]]:
    """Every dialect file the dialect was loaded from (the base, dissectors/, --dialect) and, after each,
    the files it includes (breadth first, each once, as the loader walks them), hashed: in the order loaded,
    each with the file that included it (None for those loaded themselves)."""
    cache = cache_dir(None)
    out: list[dict[str, object]] = []
    seen: set[Path] = set()
    for top in dialect.files:
        root = Path(top).resolve()
        queue: list[tuple[Path, str | None]] = [(root, None)]
        while queue and len(seen) < MAX_FILES * max(1, len(dialect.files)):
            path, by = queue.pop(0)
            if path in seen:
                continue
            seen.add(path)
            out.append({**file_hash(str(path) if by is not None else top).to_json(), "included_by": by})
            for inc in record_of(path, cache)["include"]:
                queue.append((include_path(path, inc, root.parent), path.name))
    return out


def key_names(specs: Sequence[str]) -> list[str]:
    """What the report says of each --key, --cipher, --wifi-key or --ecdh-private given: the key's name
    where the spec names one (NAME=SPEC), else only its kind (hex, passphrase, file...): never the secret."""
    out = []
    for spec in specs:
        name, eq, rest = spec.partition("=")
        if eq and name and ":" not in name:
            out.append(name)
            continue
        kind = spec.split(":", 1)[0] if ":" in spec else "key"
        out.append(f"({kind}, unnamed)")
    return out


def rule_files(paths: Sequence[str], *, default: bool) -> list[dict[str, object]]:
    """The detection rule files the audit ran (the shipped pack's unless `default` is False, then those of
    `paths`), hashed, each marked as the pack's or not."""
    out = [{**file_hash(str(f)).to_json(), "pack": True} for f in (pack_files() if default else [])]
    return out + [{**file_hash(str(f)).to_json(), "pack": False} for p in paths for f in rule_files_of(p)]


def now_utc() -> str:
    """The time of the analysis, ISO 8601 in UTC to the second."""
    return datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def tool() -> dict[str, object]:
    """mavscope's version, the Python and pymavlink versions that read the dialects."""
    import pymavlink

    return {"name": "mavscope", "version": __version__, "python": platform.python_version(),
            "pymavlink": getattr(pymavlink, "__version__", "unknown")}
