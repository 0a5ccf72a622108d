"""The dialect cache (mavscope.mavlink.dialect_cache): a cached dialect is the dialect a fresh parse gives,
an edited XML is parsed again, and an entry that is damaged, misshapen or not private is ignored.

The reference is the fresh parse (MAVSCOPE_NO_CACHE) and, independently of mavscope, pymavlink's own
generated module for all.xml (`pymavlink.dialects.v20.all`: every message's name, CRC_EXTRA, field
order and wire length as mavgen made them from the same XML). Every cache here lives under tmp_path.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import time
from pathlib import Path

import orjson
import pymavlink
import pytest

from mavscope.errors import DialectError
from mavscope.mavlink import dialect_cache
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.mavlink.dialect_cache import CACHE_ENV, NO_CACHE_ENV, cache_dir, valid_record, xml_record

V20 = Path(pymavlink.__file__).parent / "dialects" / "v20"
FRESH = {NO_CACHE_ENV: "1"}

USER_XML = """<?xml version="1.0"?>
<mavlink>
  <include>{include}</include>
  <enums>
    <enum name="TEST_MODE" bitmask="true">
      <entry value="1" name="TEST_MODE_A"><description>first</description></entry>
      <entry value="4" name="TEST_MODE_B"/>
    </enum>
  </enums>
  <messages>
    <message id="{mid}" name="TEST_USER">
      <description>a user dialect</description>
      <field type="{kind}" name="speed" units="m/s">speed</field>
      <field type="uint8_t" name="mode" enum="TEST_MODE">mode</field>
      <field type="char[10]" name="label">label</field>
    </message>
  </messages>
</mavlink>
"""

INCLUDED_XML = """<?xml version="1.0"?>
<mavlink>
  <messages>
    <message id="65201" name="TEST_INCLUDED">
      <description>included</description>
      <field type="{kind}" name="value">value</field>
    </message>
  </messages>
</mavlink>
"""


def snapshot(d: Dialect) -> tuple:
    """Everything a dialect holds, decoders included (run on one fixed payload per message)."""
    payload = bytes(range(256))
    return (list(d.messages.items()), [(m.crc_extra_byte, m.decode(payload[: m.length]), m.decode(b"\x05"))
                                       for m in d.messages.values()],
            list(d.by_name), list(d.enums.items()), d.files, d.warnings)


def user_dialect(folder: Path, kind: str = "float", included_kind: str = "int32_t") -> Path:
    folder.mkdir(exist_ok=True)
    (folder / "included.xml").write_text(INCLUDED_XML.format(kind=included_kind))
    path = folder / "user.xml"
    path.write_text(USER_XML.format(include="included.xml", mid=65200, kind=kind))
    return path


def load(folder: Path, cache: Path | None) -> Dialect:
    environ = FRESH if cache is None else {CACHE_ENV: str(cache)}
    return load_dialect(dissectors=folder, environ=environ)


def entries(cache: Path) -> list[Path]:
    return sorted(p for p in cache.glob("*.json") if not p.name.startswith("."))


def _no_parse(path: Path) -> None:
    raise AssertionError(f"{path} parsed, not read from the cache")


def test_cached_dialect_equals_fresh_parse(tmp_path: Path) -> None:
    folder = tmp_path / "dissectors"
    user_dialect(folder)
    fresh = snapshot(load(folder, None))
    cache = tmp_path / "cache"
    first = snapshot(load(folder, cache))  # parsed, then stored
    assert len(entries(cache)) == 19  # all.xml and the 16 files it includes, user.xml, included.xml
    assert first == fresh
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(dialect_cache, "parse_xml", _no_parse)
        second = snapshot(load(folder, cache))  # every file from the cache
    assert second == fresh


def test_cached_dialect_matches_pymavlinks_generated_module(tmp_path: Path) -> None:
    """Independent truth: pymavlink's mavgen output for all.xml (names, CRC_EXTRA, wire order, lengths)."""
    from pymavlink.dialects.v20 import all as generated

    cache = tmp_path / "cache"
    load_dialect(environ={CACHE_ENV: str(cache)})
    cached = load_dialect(environ={CACHE_ENV: str(cache)})
    assert set(generated.mavlink_map) <= set(cached.messages)
    for mid, cls in generated.mavlink_map.items():
        m = cached.messages[mid]
        assert (m.name, m.crc_extra, m.length) == (cls.msgname, cls.crc_extra, cls.unpacker.size), mid
        assert [f.name for f in m.fields] == cls.ordered_fieldnames, mid
        assert list(m.xml_order) == cls.fieldnames, mid


@pytest.mark.parametrize("xml", sorted(p.name for p in V20.glob("*.xml")))
def test_every_pymavlink_dialect_record_is_plain_json_of_the_checked_shape(xml: str) -> None:
    """A record that failed valid_record, or changed through JSON, would never be served from the cache."""
    record = dialect_cache.parse_xml(V20 / xml)
    assert valid_record(record)
    assert orjson.loads(orjson.dumps(record)) == record


def test_editing_a_user_dialect_or_an_included_file_invalidates(tmp_path: Path) -> None:
    folder, cache = tmp_path / "dissectors", tmp_path / "cache"
    user_dialect(folder, kind="float")
    before = load(folder, cache)
    assert before.by_name["TEST_USER"].fields[0].type == "float"
    user_dialect(folder, kind="double", included_kind="int32_t")  # user.xml edited
    after = load(folder, cache)
    assert snapshot(after) == snapshot(load(folder, None))
    assert after.by_name["TEST_USER"].fields[0].type == "double"
    assert after.by_name["TEST_USER"].length == before.by_name["TEST_USER"].length + 4
    user_dialect(folder, kind="double", included_kind="uint64_t")  # only the included file edited
    again = load(folder, cache)
    assert again.by_name["TEST_INCLUDED"].fields[0].type == "uint64_t"
    assert snapshot(again) == snapshot(load(folder, None))


def _rewrite(path: Path, body: bytes, key: str | None = None) -> None:
    """An entry with a correct header (key, SHA-256 of the body) around `body`."""
    header = {"key": key or path.stem, "sha256": hashlib.sha256(body).hexdigest()}
    path.write_bytes(orjson.dumps(header) + b"\n" + body)


def _body(path: Path) -> dict:
    return orjson.loads(path.read_bytes().partition(b"\n")[2])


def _mislead(record: dict) -> dict:
    """The same record with every CRC_EXTRA changed: wrong if served."""
    for m in record["messages"]:
        m[2] = (m[2] + 1) % 256
    return record


def _bad_layout(record: dict) -> dict:
    for m in record["messages"]:
        if m[7]:
            m[7][0][3] += 1  # the first field's offset moved
    return record


DAMAGE = {
    "truncated": lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),
    "empty": lambda p: p.write_bytes(b""),
    "no header": lambda p: p.write_bytes(p.read_bytes().partition(b"\n")[2]),
    "byte changed": lambda p: p.write_bytes(p.read_bytes().replace(b"a user dialect", b"a user dialecT")),
    "not json": lambda p: _rewrite(p, b"\x80\x04\x95 pickle? cos\nsystem\n"),
    "another file's entry": lambda p: p.write_bytes(min(entries(p.parent), key=lambda e: e.stat().st_size
                                                        if e != p else 1 << 40).read_bytes()),
    "wrong shape": lambda p: _rewrite(p, b'{"include": [], "messages": [[1, 2]], "enums": []}'),
    "wrong types": lambda p: _rewrite(p, b'{"include": [], "messages": [], "enums": [["E", 1, "", []]]}'),
    "deep nesting": lambda p: _rewrite(p, b"[" * 100000 + b"]" * 100000),
    "bad layout": lambda p: _rewrite(p, orjson.dumps(_bad_layout(_body(p)))),
    "world writable": lambda p: (_rewrite(p, orjson.dumps(_mislead(_body(p)))),
                                 p.chmod(0o666)),
    "symlink": lambda p: (_rewrite(p.with_suffix(".real"), orjson.dumps(_mislead(_body(p))), key=p.stem), p.unlink(),
                          p.symlink_to(p.with_suffix(".real").name)),
    "directory": lambda p: (p.unlink(), p.mkdir()),
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_damaged_or_hostile_entry_is_ignored(damage: str, tmp_path: Path) -> None:
    folder, cache = tmp_path / "dissectors", tmp_path / "cache"
    user_dialect(folder)
    fresh = snapshot(load(folder, None))
    load(folder, cache)
    for path in entries(cache):
        DAMAGE[damage](path)
    assert snapshot(load(folder, cache)) == fresh


def misleading_cache(tmp_path: Path) -> tuple[Path, Path]:
    """A user dialect and a cache whose every entry is well formed, private and has a correct header, but
    holds wrong CRC_EXTRAs: served as it is, it would mislead (the first test shows it is)."""
    folder, cache = tmp_path / "dissectors", tmp_path / "cache"
    user_dialect(folder)
    load(folder, cache)
    for path in entries(cache):
        _rewrite(path, orjson.dumps(_mislead(_body(path))))
    return folder, cache


def test_a_private_well_formed_entry_is_served_as_it_is(tmp_path: Path) -> None:
    """The control of the tests below: the user's own entries are trusted like the user's own XML."""
    folder, cache = misleading_cache(tmp_path)
    served, fresh = load(folder, cache), load(folder, None)
    assert served.by_name["TEST_USER"].crc_extra == (fresh.by_name["TEST_USER"].crc_extra + 1) % 256


def test_an_entry_owned_by_someone_else_is_ignored(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder, cache = misleading_cache(tmp_path)
    monkeypatch.setattr(os, "getuid", lambda: os.stat(cache).st_uid + 1)  # the files are now another user's
    assert snapshot(load(folder, cache)) == snapshot(load(folder, None))


def test_a_cache_directory_others_can_write_is_not_used(tmp_path: Path) -> None:
    folder, cache = misleading_cache(tmp_path)
    cache.chmod(0o777)  # anyone could have put these files there
    assert snapshot(load(folder, cache)) == snapshot(load(folder, None))


def test_an_entry_over_the_size_limit_is_ignored(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder, cache = misleading_cache(tmp_path)
    monkeypatch.setattr(dialect_cache, "MAX_ENTRY", 100)
    assert snapshot(load(folder, cache)) == snapshot(load(folder, None))


def test_missing_cache_directory_is_made_private(tmp_path: Path) -> None:
    folder, cache = tmp_path / "dissectors", tmp_path / "a" / "b" / "cache"
    user_dialect(folder)
    load(folder, cache)
    assert cache.stat().st_mode & 0o777 == 0o700
    assert all(p.stat().st_mode & 0o777 == 0o600 for p in entries(cache))


def test_an_unwritable_cache_still_loads(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "dissectors"
    user_dialect(folder)
    fresh = snapshot(load(folder, None))
    not_a_dir = tmp_path / "file"
    not_a_dir.write_text("")
    assert snapshot(load(folder, not_a_dir / "cache")) == fresh  # mkdir fails
    read_only = tmp_path / "read-only"
    read_only.mkdir(mode=0o700)

    def refuse(*args: object, **kwargs: object) -> None:
        raise PermissionError("read-only file system")

    monkeypatch.setattr(tempfile, "mkstemp", refuse)  # root ignores mode bits: refuse the write
    assert snapshot(load(folder, read_only)) == fresh
    assert entries(read_only) == []


def test_no_cache_writes_nothing(tmp_path: Path) -> None:
    folder, cache = tmp_path / "dissectors", tmp_path / "cache"
    user_dialect(folder)
    load_dialect(dissectors=folder, environ={CACHE_ENV: str(cache), NO_CACHE_ENV: "1"})
    assert not cache.exists()


def test_a_broken_xml_is_reported_and_never_cached(tmp_path: Path) -> None:
    folder, cache = tmp_path / "dissectors", tmp_path / "cache"
    folder.mkdir()
    (folder / "broken.xml").write_text("<mavlink><messages><message id='1'")
    with pytest.raises(DialectError) as fresh:
        load(folder, None)
    with pytest.raises(DialectError) as cached:
        load(folder, cache)
    assert str(cached.value) == str(fresh.value)
    assert str(fresh.value).startswith(f"{(folder / 'broken.xml').resolve()}: cannot parse dialect: ")
    assert len(entries(cache)) == 17  # all.xml's files, not the broken one


def test_a_dialect_declaring_entities_is_refused_before_pymavlink_parses_it(tmp_path: Path,
                                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """An entity expansion bomb in a dialect file: expat stops it after some 8 MB of expansion, which took
    pymavlink's character handler 35 s (stop 20). No MAVLink dialect declares an entity: refused unread by
    pymavlink, one line; a DOCTYPE without entities still parses."""
    from pymavlink.generator import mavparse

    folder = tmp_path / "dissectors"
    folder.mkdir()
    laughs = "".join(f'<!ENTITY l{i} "{f"&l{i - 1};" * 10}">' for i in range(1, 10))
    (folder / "bomb.xml").write_text(f'<?xml version="1.0"?>\n<!DOCTYPE m [<!ENTITY l0 "lol">{laughs}]>\n'
                                     '<mavlink><messages><message id="60000" name="BOMB"><description>&l9;'
                                     '</description><field type="uint8_t" name="a">a</field></message></messages>'
                                     "</mavlink>\n")
    parsed: list[bytes] = []  # what pymavlink's parser was given to read (a copy of the bytes checked)
    real = mavparse.MAVXML
    monkeypatch.setattr(mavparse, "MAVXML", lambda path, *a: parsed.append(Path(path).read_bytes()) or real(path, *a))
    with pytest.raises(DialectError) as refused:
        load(folder, None)
    assert str(refused.value) == (f"{(folder / 'bomb.xml').resolve()}: cannot load dialect: line 2: it has a "
                                  "DOCTYPE declaring entities or naming a DTD, which MAVLink dialects do not use")
    assert not any(b"BOMB" in data for data in parsed)
    (folder / "bomb.xml").unlink()
    user = user_dialect(folder)
    user.write_text(user.read_text().replace('<?xml version="1.0"?>', '<?xml version="1.0"?>\n<!DOCTYPE mavlink>'))
    assert "TEST_MODE" in load(folder, None).enums
    assert any(b"<!DOCTYPE mavlink>" in data for data in parsed)


@pytest.mark.parametrize(("environ", "expected"), [
    ({NO_CACHE_ENV: "1", CACHE_ENV: "/c"}, None),
    ({CACHE_ENV: "/c", "XDG_CACHE_HOME": "/x", "HOME": "/h"}, Path("/c")),
    ({NO_CACHE_ENV: "", "XDG_CACHE_HOME": "/x", "HOME": "/h"}, Path("/x/mavscope")),
    ({"XDG_CACHE_HOME": "relative", "HOME": "/h"}, Path("/h/.cache/mavscope")),  # XDG: relative is ignored
    ({"HOME": "/h"}, Path("/h/.cache/mavscope")),
])
def test_cache_dir(environ: dict[str, str], expected: Path | None, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("HOME", environ.get("HOME", "/h"))
    assert cache_dir(environ) == expected


def test_xml_record_keeps_what_the_dialect_needs() -> None:
    """By hand from minimal.xml: HEARTBEAT (id 0, CRC_EXTRA 50, 9 bytes, uint32 first on the wire)."""
    from pymavlink.generator import mavparse

    record = xml_record(mavparse.MAVXML(str(V20 / "minimal.xml"), "2.0"))
    heartbeat = next(m for m in record["messages"] if m[1] == "HEARTBEAT")
    assert heartbeat[:5] == [0, "HEARTBEAT", 50, 9, 9]
    assert [f[0] for f in heartbeat[7]] == ["custom_mode", "type", "autopilot", "base_mode", "system_status",
                                            "mavlink_version"]
    assert heartbeat[6] == ["type", "autopilot", "base_mode", "custom_mode", "system_status", "mavlink_version"]


def test_a_file_edited_while_parsed_caches_what_was_parsed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The file is read once: its bytes are checked, parsed and name the entry. Edited during the parse,
    the entry holds the record of the bytes read (named by them), and the next run parses the new bytes:
    no entry ever names bytes other than those it was parsed from."""
    folder, cache = tmp_path / "dissectors", tmp_path / "cache"
    user = user_dialect(folder)
    parse = dialect_cache.parse_data

    def parse_then_edit(data: bytes, path: Path) -> dict:
        record = parse(data, path)
        if path.name == "user.xml":
            path.write_text(USER_XML.format(include="included.xml", mid=65200, kind="double"))
        return record

    monkeypatch.setattr(dialect_cache, "parse_data", parse_then_edit)
    first = load(folder, cache)
    assert first.by_name["TEST_USER"].field("speed").type == "float"  # the bytes read before the edit
    assert len(entries(cache)) == 19
    monkeypatch.setattr(dialect_cache, "parse_data", parse)
    again = load(folder, cache)
    assert again.by_name["TEST_USER"].field("speed").type == "double"  # the new bytes, parsed afresh
    assert snapshot(again) == snapshot(load(folder, None))
    assert user.read_text().count("double") == 1


def _fake_entry(cache: Path, n: int, age: float) -> Path:
    """An entry-named file written `age` seconds ago (its content does not matter to pruning)."""
    path = cache / f"{hashlib.sha256(str(n).encode()).hexdigest()}.json"
    path.write_text("{}")
    when = time.time() - age
    os.utime(path, (when, when))
    return path


def test_writing_keeps_the_cache_bounded_least_recently_used_out_first(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A version change names every file anew: without pruning, each one left its entries behind for good.
    Expected by construction: the dialect's own entries and, up to the limit, the youngest of the fakes."""
    folder, cache = tmp_path / "dissectors", tmp_path / "cache"
    user_dialect(folder)
    load(folder, tmp_path / "count")
    n = len(entries(tmp_path / "count"))  # the files the dialect loads (all.xml's and the user's)
    cache.mkdir(mode=0o700)
    monkeypatch.setattr(dialect_cache, "MAX_ENTRIES", n + 8)
    fakes = [_fake_entry(cache, k, age=1000.0 + k) for k in range(20)]  # fakes[0] the youngest
    other = cache / "notes.txt"  # not an entry: never touched
    other.write_text("mine")
    stale = cache / ".tmp-crashed.json"  # a crashed write's, two hours old
    stale.write_text("{")
    os.utime(stale, (time.time() - 7200,) * 2)
    fresh_temp = cache / ".tmp-in-progress.json"  # another process writing right now
    fresh_temp.write_text("{")
    fresh = snapshot(load(folder, None))
    assert snapshot(load(folder, cache)) == fresh  # parsed (the fakes are not its entries) and written
    kept = entries(cache)
    assert len(kept) == n + 8
    assert sorted(p for p in kept if p in fakes) == sorted(fakes[:8])
    assert other.read_text() == "mine" and fresh_temp.exists() and not stale.exists()
    monkeypatch.setattr(dialect_cache, "parse_xml", _no_parse)
    assert snapshot(load(folder, cache)) == fresh  # its entries all kept: served without a parse


def test_an_entry_read_after_a_day_is_touched_so_it_outlives_unread_ones(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    folder, cache = tmp_path / "dissectors", tmp_path / "cache"
    user_dialect(folder)
    load(folder, cache)
    mine = entries(cache)
    old = time.time() - 3 * 86_400
    for p in mine:
        os.utime(p, (old, old))
    fakes = [_fake_entry(cache, n, age=86_400.0) for n in range(5)]  # younger than ours, never read
    monkeypatch.setattr(dialect_cache, "parse_xml", _no_parse)
    load(folder, cache)  # served from the cache: ours touched
    assert all(p.stat().st_mtime > time.time() - 60 for p in mine)
    dialect_cache.prune(cache, limit=len(mine))
    assert entries(cache) == mine and not any(p.exists() for p in fakes)


def test_an_entry_read_within_a_day_of_its_write_is_left_as_it_is(tmp_path: Path) -> None:
    """No write per run: the touch happens at most once a day per entry."""
    folder, cache = tmp_path / "dissectors", tmp_path / "cache"
    user_dialect(folder)
    load(folder, cache)
    before = {p: p.stat().st_mtime_ns for p in entries(cache)}
    load(folder, cache)
    assert {p: p.stat().st_mtime_ns for p in entries(cache)} == before
