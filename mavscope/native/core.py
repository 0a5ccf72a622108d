"""The one door to the C extension: its import, the engine choice, and the contract's constants.

`mavscope._native` is optional (setup.py builds it where a compiler is found); every module that talks to
it imports it from here (`from mavscope.native.core import _native`), and chooses the engine here:

- `available(environ)`: whether the native engine runs: the extension is built and MAVSCOPE_PURE is
  unset (or empty, or 0). `engine(environ)` says the same as "native" or "pure-python".
- `KINDS`: capture kind -> the Walker's `kind` (capture.h's enum, as the module exports it: KIND_*).
- `COLUMN_TRANSPORTS`: the transport column's code (columns.h, COLUMN_TRANSPORT_*) -> the transport's
  name (None: a code never written; the names are mavscope.transport.base's); `NOTE_*`: the bits of the
  note column (columns.h MS_NOTE_*).

The typed contract of the extension is mavscope/_native.pyi (tests/meta/test_native_contract.py holds
it to the built module). Without the extension the constants are empty: nothing walks natively then.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

from mavscope.transport.base import TRANSPORT_RAW, TRANSPORT_TLOG, TRANSPORT_UDP
from mavscope.transport.dispatch import TABLES

try:
    from mavscope import _native
except ImportError:  # built without a compiler: the pure-Python path serves
    # mypy types `_native` as the module (the stub); whether it is built is `_native is not None`
    _native = None  # type: ignore[assignment]

PURE_ENV = "MAVSCOPE_PURE"  # set (but not to "" or "0"): the pure-Python engine runs, built or not
NATIVE, PURE = "native", "pure-python"  # engine()'s answers


def available(environ: Mapping[str, str] | None = None) -> bool:
    """Whether the native engine runs: the extension is built, MAVSCOPE_PURE is not set and the transport's
    dispatch tables are the built-in ones (the native core decodes those alone: a link type, protocol or port
    bound with transport.dispatch is read by the Python pipeline)."""
    env = os.environ if environ is None else environ
    return _native is not None and env.get(PURE_ENV, "") in ("", "0") and TABLES.builtin()


def engine(environ: Mapping[str, str] | None = None) -> str:
    """Which engine runs: "native", or "pure-python" (no extension, or MAVSCOPE_PURE set)."""
    return NATIVE if available(environ) else PURE


def _by_code(codes: Mapping[int, str]) -> tuple[str | None, ...]:
    """A tuple indexed by code: the name of each code, None where there is none."""
    return tuple(codes.get(k) for k in range(max(codes, default=-1) + 1))


KINDS: Mapping[str, int] = {}
COLUMN_TRANSPORTS: tuple[str | None, ...] = ()
NOTE_UNSIGNED = NOTE_V1 = NOTE_BAD_CRC = 0  # the note column's bits (columns.h MS_NOTE_*)
if _native is not None:
    KINDS = {"pcap": _native.KIND_PCAP, "pcapng": _native.KIND_PCAPNG, "tlog": _native.KIND_TLOG,
             "raw": _native.KIND_RAW}
    NOTE_UNSIGNED, NOTE_V1, NOTE_BAD_CRC = _native.NOTE_UNSIGNED, _native.NOTE_V1, _native.NOTE_BAD_CRC
    COLUMN_TRANSPORTS = _by_code({_native.COLUMN_TRANSPORT_UDP: TRANSPORT_UDP,
                                  _native.COLUMN_TRANSPORT_TLOG: TRANSPORT_TLOG,
                                  _native.COLUMN_TRANSPORT_RAW: TRANSPORT_RAW})
