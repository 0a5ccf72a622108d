"""What mavscope takes from pymavlink's parser for one dialect XML file, as plain data, and a cache of it.

Parsing the XML (pymavlink's `mavparse`) is most of the cost of loading a dialect (about 0.08 s of 0.1 s
for all.xml and the 16 files it includes), paid by every run. `xml_record(xml)` turns one parsed file
into a *record*: lists, strings, ints and bools only, exactly what `mavscope.mavlink.dialect` builds its
messages and enums from. `record_of(path, directory)` gives a file's record, from the cache when it holds
one, else parsed (and then stored). A file is read once (`read_dialect`: a regular file, bounded), checked
(mavscope.mavlink.dialect_check: dialect files are input) and parsed from those very bytes.

The cache is content-addressed: an entry is named by the SHA-256 of the file's bytes salted with the
cache format, mavscope's version, this module's and dialect_check's source, pymavlink's version and
parser file, and the Python version. Editing any XML (one in `dissectors/`, one a dialect includes)
gives a new name, so a stale entry is never read; includes are resolved against the real path every run.

Trust: an entry is plain JSON (never pickle or marshal, which can run code or crash on crafted bytes)
in a directory the user owns. It is read only when the directory and the file are owned by the user and
not writable by group or others, the file is a regular file (not a symlink) under 16 MiB, its header
names the expected key, the SHA-256 of its body matches the header, and the body has exactly the record's
shape with consistent layouts and identifiers for names (`valid_record`). Anything else is ignored and
the XML parsed afresh.
Writing is best effort (a temporary file renamed into place); a read-only or missing directory only
costs the parse. Each write keeps the directory bounded: at most MAX_ENTRIES entries, those least
recently used removed first (an entry read a day or more after its last write or touch is touched; a new
mavscope, pymavlink or Python names every file anew, so the entries of the version left behind age
out), and temporary files a crashed write left behind over an hour ago.

Where: `$MAVSCOPE_CACHE_DIR`, else `$XDG_CACHE_HOME/mavscope`, else `~/.cache/mavscope`; `MAVSCOPE_NO_CACHE`
set to anything but empty turns the cache off.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import stat
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from mavscope.errors import DialectError
from mavscope.mavlink import dialect_check
from mavscope.mavlink.dialect_check import MAX_ARRAY, MAX_FIELDS, MAX_FILE_BYTES, check_xml, names_valid, too_big

CACHE_ENV = "MAVSCOPE_CACHE_DIR"
NO_CACHE_ENV = "MAVSCOPE_NO_CACHE"
FORMAT = b"mavscope dialect cache 1"
MAX_ENTRY = 16 << 20  # bytes: all.xml's largest file gives about 0.5 MB
MAX_ENTRIES = 256  # entries kept (one version: about 20, all.xml's 17 files and dissectors/; 40 KB each)
STALE_TEMP = 3600  # seconds after which a `.tmp-*` file is a crashed write's, not one in progress
TOUCH_AFTER = 86_400  # seconds: an entry read this long after it was written (or last touched) is touched

Record = dict[str, Any]  # {"include": [str], "messages": [message], "enums": [enum]}: see xml_record

# Wire type -> bytes of one element (mavparse's type names).
TYPE_SIZE = {"float": 4, "double": 8, "char": 1, "int8_t": 1, "uint8_t": 1, "uint8_t_mavlink_version": 1,
             "int16_t": 2, "uint16_t": 2, "int32_t": 4, "uint32_t": 4, "int64_t": 8, "uint64_t": 8}


def _text(value: object) -> str:
    """An XML description in one line (runs of white space as one space)."""
    return " ".join(str(value or "").split())


def xml_record(xml: Any) -> Record:
    """The record of one parsed file (a pymavlink MAVXML):
    - include: the `<include>` file names, as written;
    - messages: [id, name, crc_extra, base_length, length, description, xml_order, fields], with fields
      in wire order, each [name, type, array_length, offset, size, extension, units, enum, display,
      description, print_format];
    - enums: [name, bitmask, description, entries], each entry [name, value, description, params,
      param_enums] (params: [index, label, units] of the labelled ones; param_enums: [index, enum]);
      the `*_ENUM_END` markers left out."""
    messages = []
    for m in xml.message:
        base_count = m.base_fields()
        fields = [[f.name, f.type, f.array_length, f.wire_offset, f.wire_length, i >= base_count,
                   (f.units or "").strip("[] "), f.enum or "", f.display or "", _text(f.description),
                   f.print_format or ""] for i, f in enumerate(m.ordered_fields)]
        messages.append([m.id, m.name, m.crc_extra, m.wire_min_length, m.wire_length, _text(m.description),
                         list(m.fieldnames), fields])
    enums = []
    for e in xml.enum:
        entries = []
        for entry in e.entry:
            if entry.name.endswith("_ENUM_END"):
                continue
            used = [p for p in entry.param if not getattr(p, "reserved", False)]
            params = [[int(p.index), (p.label or "").strip(), (p.units or "").strip()]
                      for p in used if (p.label or "").strip()]
            param_enums = [[int(p.index), p.enum.strip()] for p in used if (getattr(p, "enum", "") or "").strip()]
            entries.append([entry.name, entry.value, _text(entry.description), params, param_enums])
        enums.append([e.name, bool(getattr(e, "bitmask", False)), _text(e.description), entries])
    return {"include": list(xml.include), "messages": messages, "enums": enums}


def read_dialect(path: Path) -> bytes:
    """The bytes of the dialect file `path`: a regular file (never a FIFO, device or /proc file that would
    block or never end) of at most dialect_check.MAX_FILE_BYTES, read once (DialectError otherwise)."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as e:
        raise DialectError(f"{path}: cannot read dialect: {e.strerror or e}") from None
    with os.fdopen(fd, "rb") as f:
        try:
            st = os.fstat(f.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise DialectError(f"{path}: cannot read dialect: not a regular file")
            if st.st_size > MAX_FILE_BYTES:
                raise DialectError(too_big(str(path)))
            data = f.read(MAX_FILE_BYTES + 1)
        except OSError as e:
            raise DialectError(f"{path}: cannot read dialect: {e.strerror or e}") from None
    return data


@contextlib.contextmanager
def _copy_of(data: bytes, path: Path) -> Iterator[str]:
    """A file name with the bytes `data` for mavparse to open: an anonymous in-memory file (Linux), else a
    private temporary file, else (neither can be made: no /proc, a read-only temporary folder) `path`
    itself, then read again after the parse (DialectError if it changed meanwhile)."""
    fd = -1
    with contextlib.suppress(OSError, AttributeError):
        fd = os.memfd_create("mavscope-dialect", getattr(os, "MFD_CLOEXEC", 0))
    if fd >= 0:
        try:
            os.write(fd, data)
            name = f"/proc/self/fd/{fd}"
            if os.path.exists(name):
                yield name
                return
        finally:
            os.close(fd)
    try:
        fd, copy = tempfile.mkstemp(prefix="mavscope-dialect-", suffix=".xml")  # mode 0600
    except OSError:
        yield str(path)
        if read_dialect(path) != data:
            raise DialectError(f"{path}: cannot load dialect: the file changed while it was read") from None
        return
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        yield copy
    finally:
        with contextlib.suppress(OSError):
            os.unlink(copy)


def parse_data(data: bytes, path: Path) -> Record:
    """Parse the bytes `data` of the dialect file `path` with pymavlink (v2.0 definitions) into its record,
    once they pass mavscope.mavlink.dialect_check (bounded time and memory, identifiers for names). The
    parser reads a copy of those bytes (`_copy_of`): what is parsed is what was checked (and what names
    the cache entry), whatever happens to the file meanwhile."""
    from pymavlink.generator import mavparse

    check_xml(data, str(path))
    with _copy_of(data, path) as name:
        try:
            # mavparse prints warnings about upstream XML to stdout; keep our output clean.
            with contextlib.redirect_stdout(io.StringIO()):
                xml = mavparse.MAVXML(name, "2.0")
        except Exception as exc:  # mavparse raises bare Exceptions and ExpatErrors
            raise DialectError(f"{path}: cannot parse dialect: {exc}") from exc
    return xml_record(xml)


def parse_xml(path: Path) -> Record:
    """Parse one dialect file with pymavlink (v2.0 definitions) into its record (`parse_data`)."""
    return parse_data(read_dialect(path), path)


def cache_dir(environ: Mapping[str, str] | None = None) -> Path | None:
    """Where entries go (module docstring), or None when the cache is off or there is no home."""
    env = os.environ if environ is None else environ
    if env.get(NO_CACHE_ENV):
        return None
    if env.get(CACHE_ENV):
        return Path(env[CACHE_ENV])
    xdg = env.get("XDG_CACHE_HOME", "")
    if os.path.isabs(xdg):  # the XDG spec: a relative path is invalid and ignored
        return Path(xdg) / "mavscope"
    try:
        return Path.home() / ".cache" / "mavscope"
    except (RuntimeError, KeyError):  # no HOME and no password entry
        return None


_SALT: bytes | None = None


def _salt() -> bytes:
    """What an entry's name depends on besides the XML (module docstring); computed once."""
    global _SALT
    if _SALT is None:
        import pymavlink  # its parser is not imported: with every file cached, it is never needed

        from mavscope import __version__

        parser = os.stat(Path(pymavlink.__file__).parent / "generator" / "mavparse.py")
        own = Path(__file__).read_bytes() + Path(dialect_check.__file__).read_bytes()
        parts = [FORMAT, __version__.encode(), hashlib.sha256(own).digest(),
                 str(getattr(pymavlink, "__version__", "")).encode(), f"{parser.st_size}:{parser.st_mtime_ns}".encode(),
                 sys.version.encode()]
        _SALT = b"\0".join(parts) + b"\0"
    return _SALT


def entry_key(data: bytes) -> str:
    """The name of the entry for an XML file with these bytes."""
    return hashlib.sha256(_salt() + data).hexdigest()


def record_of(path: Path, directory: Path | None) -> Record:
    """The record of the dialect file `path`: cached in `directory` (None: no cache) or parsed."""
    data = read_dialect(path)
    if directory is None:
        return parse_data(data, path)
    key = entry_key(data)
    cached = read_entry(directory, key)
    if cached is not None:
        return cached
    record = parse_data(data, path)  # the bytes named by the key
    write_entry(directory, key, record)
    return record


def _private(st: os.stat_result) -> bool:
    """Owned by this user and not writable by anyone else."""
    return st.st_uid == os.getuid() and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def read_entry(directory: Path, key: str) -> Record | None:
    """The record stored under `key`, or None when there is none or it cannot be trusted (module docstring)."""
    import orjson

    try:
        if not _private(os.stat(directory)):
            return None
        fd = os.open(directory / f"{key}.json", os.O_RDONLY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0))
        with os.fdopen(fd, "rb") as f:
            st = os.fstat(f.fileno())
            if not stat.S_ISREG(st.st_mode) or not _private(st) or st.st_size > MAX_ENTRY:
                return None
            blob = f.read(MAX_ENTRY + 1)
            if time.time() - st.st_mtime > TOUCH_AFTER:  # in use: pruned after the entries not read
                with contextlib.suppress(OSError):
                    os.utime(f.fileno())
        head, sep, body = blob.partition(b"\n")
        header = orjson.loads(head)
        if (not sep or not isinstance(header, dict) or header.get("key") != key
                or header.get("sha256") != hashlib.sha256(body).hexdigest()):
            return None
        record = orjson.loads(body)
    except (OSError, ValueError):  # orjson.JSONDecodeError is a ValueError
        return None
    return record if valid_record(record) else None


def write_entry(directory: Path, key: str, record: Record) -> None:
    """Store `record` under `key`, best effort: nothing happens when the directory cannot be made private
    or written, or the record is not plain JSON."""
    import orjson

    try:
        body = orjson.dumps(record)
    except TypeError:  # an int beyond 64 bits, a lone surrogate: not cached, parsed every run
        return
    if len(body) > MAX_ENTRY - 200:  # never read back (read_entry): not worth writing
        return
    head = orjson.dumps({"key": key, "sha256": hashlib.sha256(body).hexdigest()})
    try:
        directory.mkdir(mode=0o700, parents=True, exist_ok=True)
        if not _private(os.stat(directory)):
            return
        fd, tmp = tempfile.mkstemp(dir=directory, prefix=".tmp-", suffix=".json")  # mode 0600
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(head + b"\n" + body)
            os.replace(tmp, directory / f"{key}.json")
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
        prune(directory)
    except OSError:
        return


def _is_entry_name(name: str) -> bool:
    stem, _, ext = name.partition(".")
    return ext == "json" and len(stem) == 64 and all(c in "0123456789abcdef" for c in stem)


def prune(directory: Path, limit: int | None = None) -> None:
    """Keep at most `limit` (MAX_ENTRIES) entries in `directory`, removing those least recently written or
    touched, and remove temporary files older than STALE_TEMP seconds. Only the user's own regular files
    named as entries or temporary files are touched; a file gone meanwhile (another process) is skipped."""
    limit = MAX_ENTRIES if limit is None else limit
    found: list[tuple[int, str]] = []
    stale = time.time() - STALE_TEMP
    with os.scandir(directory) as it:
        for e in it:
            entry, temp = _is_entry_name(e.name), e.name.startswith(".tmp-") and e.name.endswith(".json")
            if not (entry or temp):
                continue
            try:
                st = e.stat(follow_symlinks=False)
            except OSError:
                continue
            if not stat.S_ISREG(st.st_mode) or st.st_uid != os.getuid():
                continue
            if entry:
                found.append((st.st_mtime_ns, e.name))
            elif st.st_mtime < stale:
                with contextlib.suppress(OSError):
                    os.unlink(e.path)
    if len(found) <= limit:
        return
    found.sort()
    for _mtime, name in found[:len(found) - limit]:
        with contextlib.suppress(OSError):
            os.unlink(directory / name)


# The types of a record's lists, item by item (xml_record): one map(type, ...) checks a whole list.
_FIELD = (str, str, int, int, int, bool, str, str, str, str, str)
_MESSAGE = (int, str, int, int, int, str, list, list)
_ENUM = (str, bool, str, list)
_ENTRY = (str, int, str, list, list)
_PARAM = (int, str, str)
_PARAM_ENUM = (int, str)
# a layout's longest: every field an array of 255 eight-byte values (a payload over 255 bytes is a layout
# pymavlink accepts too: frames of it carry its first 255 bytes at most)
_MAX_LENGTH = MAX_FIELDS * MAX_ARRAY * 8


def _valid_message(m: Any) -> bool:
    if type(m) is not list or tuple(map(type, m)) != _MESSAGE:
        return False
    mid, _, crc_extra, base_length, length, _, order, fields = m
    if not (0 <= mid < 1 << 24 and 0 <= crc_extra <= 255 and 0 <= base_length <= length <= _MAX_LENGTH
            and len(fields) <= MAX_FIELDS and all(type(o) is str for o in order)):
        return False
    offset = 0
    for f in fields:
        if type(f) is not list or tuple(map(type, f)) != _FIELD:
            return False
        kind, count, at, size = f[1], f[2], f[3], f[4]
        if at != offset or kind not in TYPE_SIZE or not 0 <= count <= 255 or size != TYPE_SIZE[kind] * max(count, 1):
            return False
        offset += size
    return offset == length


def _valid_enum(e: Any) -> bool:
    if type(e) is not list or tuple(map(type, e)) != _ENUM:
        return False
    for x in e[3]:
        if type(x) is not list or tuple(map(type, x)) != _ENTRY:
            return False
        for p in x[3]:
            if type(p) is not list or tuple(map(type, p)) != _PARAM:
                return False
        for p in x[4]:
            if type(p) is not list or tuple(map(type, p)) != _PARAM_ENUM:
                return False
    return True


def valid_record(record: Any) -> bool:
    """Whether `record` has exactly the shape `xml_record` gives, with each message's fields laid end to
    end from offset 0 to its length (a type's size times the array length), and names that are
    identifiers (dialect_check.names_valid: a cached record is held to the rules of a parsed one)."""
    return (type(record) is dict and record.keys() == {"include", "messages", "enums"}
            and type(record["include"]) is list and all(type(i) is str for i in record["include"])
            and type(record["messages"]) is list and all(map(_valid_message, record["messages"]))
            and type(record["enums"]) is list and all(map(_valid_enum, record["enums"]))
            and names_valid(record["messages"], record["enums"]))
