"""The typed contract of the C extension `mavscope._native` (src/mavscope_native/module.c, module_recv.c).

Read from the C: its PyMethodDef tables, PyGetSetDef, PyArg_ParseTuple(AndKeywords) formats and kwlists,
and the module's PyModule_Add* calls. A METH_O or METH_VARARGS function takes positional arguments only
(the `/`); a method parsed with keywords takes them by name too. "p" arguments take any object's truth
value; they are written `bool`, as every caller passes one. tests/meta/test_native_contract.py holds the
names here to the built module's, both ways. Python reaches the module through mavscope.native.core only.
"""

from collections.abc import Callable
from typing import Any, NoReturn, TypeVar, final

from typing_extensions import Buffer

_E = TypeVar("_E")  # what the Walker's `endpoint` callback makes of a packed address: `endpoints`' items
_V = TypeVar("_V")  # the receivers' values: the walker reads only the keys (UDP ports)

# (number, time, linktype, data, offset, orig_len, notes): a record the walker hands back to Python
# (capture.reader.handed_back_record); each note (code name, message, offset)
_HandedBack = tuple[int, float | None, int, bytes, int, int, tuple[tuple[str, str, int], ...]]
# the notes the walker writes itself, each cut where its values go: as many templates, each of as many pieces,
# as walk.h's MS_TPL_* say (checked when the Walker is made: TypeError); mavscope.native.walk makes them
_NoteTemplates = tuple[tuple[bytes, ...], ...]

COLUMN_NAMES: tuple[str, ...]  # the column Blocks of Columns.take, in order (columns.h MS_COL_*)
MAX_ENDPOINTS: int  # walk.h MS_MAX_ENDPOINTS: the endpoints a walker interns
KIND_PCAP: int  # capture.h MS_KIND_*: Walker's `kind`
KIND_PCAPNG: int
KIND_TLOG: int
KIND_RAW: int
COLUMN_TRANSPORT_UDP: int  # columns.h MS_TRANSPORT_*: the codes of the `transport` column (0: never written)
COLUMN_TRANSPORT_TLOG: int
COLUMN_TRANSPORT_RAW: int  # a raw byte stream's frame (no time, no endpoints: Dissector._stream's)
NOTE_UNSIGNED: int  # columns.h MS_NOTE_*: the bits of the `note` column (Columns(notes=True))
NOTE_V1: int
NOTE_BAD_CRC: int
TABLE_VERSION: int  # the layout table blob's version (table.h)
UDP_PCAP_HEADER: bytes  # the global header of the pcap live capture's records make (module_recv.c)


@final
class Table:
    """The message layouts (mavscope.native.table_blob.build_table); ValueError when malformed."""

    def __init__(self, blob: Buffer) -> None: ...
    def count(self) -> int: ...


@final
class Summary:
    """What summary lines show per message (mavscope.native.summary.build_summary_table)."""

    def __init__(self, table: Table, blob: Buffer) -> None: ...


@final
class Block:
    """Read-only bytes of a column chunk, owned by Python once taken (the buffer protocol); not made in Python."""

    def __buffer__(self, flags: int, /) -> memoryview: ...
    def __len__(self) -> int: ...


@final
class Columns:
    """The column buffers a Walker fills in column mode (columns.h); `index`: only the index's columns;
    `notes`: frames with the notes of NOTE_* are taken (their bits in the `note` column), not handed back."""

    def __init__(self, table: Table, limit: int = 65536, *, index: bool = False, notes: bool = False) -> None: ...
    @property
    def frames(self) -> int: ...
    limit: int  # frames a chunk holds (settable between walks)
    def take(self) -> tuple[int, bool, list[tuple[bytes, int]], list[Block], list[tuple[int, Block, Block, int]]]:
        """(frames, endpoints_reset, new_endpoints (packed address, port), column Blocks (COLUMN_NAMES),
        messages (position in the table, payload rows, frame positions, count))."""
        ...


@final
class SigningState:
    """The signing state the walker and SignatureVerifier share (signing.h); never copied or pickled."""

    def __init__(self) -> None: ...
    def add_key(self, secret: Buffer, name: str, /) -> int: ...
    def get(self, stream: tuple[int, int, int], /) -> tuple[int, int] | None: ...
    def put(self, stream: tuple[int, int, int], last: int, key: int, /) -> None: ...
    def __len__(self) -> int: ...
    def __reduce__(self) -> NoReturn: ...
    def __reduce_ex__(self, protocol: Any, /) -> NoReturn: ...
    def __copy__(self) -> NoReturn: ...
    def __deepcopy__(self, memo: Any, /) -> NoReturn: ...


# A raw stream's state the Walker shares with Python (mavscope.pipeline.dissect.RawLink): its int `frames` read
# before and set after each `next`, its int `held` (-1: the stream's framer is idle) read before it (JSON Lines,
# summary lines and column mode alike)
_RawLink = Any


@final
class Walker:
    """Walks a capture (pread on `fd`; -1: a pcap that grows by `feed`), writing JSON Lines, summary lines or
    columns, and handing back every record it does not take."""

    def __init__(self, fd: int, size: int, kind: int, table: Table, endpoints: set[_E],
                 endpoint: Callable[[bytes, int], _E], signed_senders: set[tuple[int, int]], window: int = ...,
                 summary: Summary | None = None, t0: float | None = None, columns: Columns | None = None,
                 receivers: dict[int, _V] | None = None,
                 notes: _NoteTemplates | None = None, ports: tuple[int, ...] | None = None,
                 raw: _RawLink | None = None) -> None: ...
    def next(self, signed_nokey: bool = False, limit: int = 1 << 20, into: bytearray | None = None,
             signing: SigningState | None = None) -> list[bytes | bytearray | _HandedBack] | None: ...
    def walked(self) -> tuple[int, float | None, int | None] | None: ...
    def stats(self) -> dict[str, int]: ...
    def feed(self, records: Buffer, /) -> None: ...
    def close(self) -> None: ...


@final
class Receiver:
    """Batched UDP receive (recvmmsg) for live capture, bound address `local` packed (4 or 16 bytes)."""

    def __init__(self, local: Buffer, local_port: int) -> None: ...
    def receive(self, fd: int, max: int, /) -> tuple[bytes, int, int, int, int]:
        """(pcap records, datagrams, payload bytes, latest SO_RXQ_OVFL or -1, ECONNREFUSED count)."""
        ...


def sha256(data: Buffer, /) -> bytes: ...
def format_skew(x: float, /) -> bytes: ...
def format_f32(x: float, layout: int, /) -> bytes: ...  # layout 0: JSON, 1: repr
def format_double_repr(x: float, /) -> bytes: ...
def format_degrees(bits: int, is_unsigned: bool, /) -> bytes: ...
def format_reltime(t: float, /) -> bytes | None: ...
def repr_ascii(b: Buffer, /) -> bytes | None: ...
def format_double(x: float, /) -> bytes: ...
def text_json(b: Buffer, /) -> bytes: ...
# each column a list of str or None (a cell per line) or an int64 buffer (a number per row); `bounds` int64
# (a line per pair), `modes` a byte f, l or a per column; the quote one character or ""
def join_fields(columns: list[Any], bounds: Buffer, modes: bytes, separator: str, quote: str, aggregator: str,
                /) -> str: ...
def records_to_micro(records: Buffer, /) -> tuple[bytes, int]: ...
def udp_record(sec: int, nsec: int, src: Buffer, sport: int, dst: Buffer, dport: int, payload: Buffer, /) -> bytes: ...
