"""Which frames a display filter can match, read from its AST: a rule is evaluated only on frames of the
messages it names (the engine's table by message id), and a rule on signature fields only on signed frames, so
a pack of rules costs a dictionary look-up on every other frame.

The answer is a `Scope`: a set of message ids (None: any message) and whether the frame must carry a signature.
It is never narrower than the filter: a frame outside it cannot match.

- `MSG` alone, and a payload field (`MSG.field`, or a bare `field`: every message that has it): the frame is
  one of those messages, since a comparison on a field the frame does not have is false, `!=` included
  (mavscope.filter's Wireshark rule); so is a field of a protocol inside one message's byte array (`ftp.*`:
  FILE_TRANSFER_PROTOCOL, `serial.*`: SERIAL_CONTROL...: CONTAINERS);
- `mavlink.msgid == N`, `mavlink.msgid in {...}` (numbers, message names, small ranges), `mavlink.msgname ==
  NAME`, `mavlink.msgname in {...}`: those messages;
- `signature` and `signature.*`: a signed frame (an unsigned one has none of them);
- `A && B`: what both ask (the intersection of the messages known); `A || B`: what either allows (any message
  when either does); `not A`: anything.
"""

from __future__ import annotations

from dataclasses import dataclass

from mavscope.fields.registry import Field, FieldRegistry, PayloadField
from mavscope.filter.parser import Name, Node, Not, Range, Test, Value, parse
from mavscope.mavlink.dialect import MessageDef

MAX_RANGE = 4096  # a msgid range wider than this is left as "any message"
MESSAGE_FIELDS = frozenset({"mavlink.msgid", "mavlink.msgname"})
# the protocols in byte arrays (mavscope.fields.containers): each prefix's fields are one message's
CONTAINERS = {"ftp": "FILE_TRANSFER_PROTOCOL", "serial": "SERIAL_CONTROL", "log": "LOG_DATA", "tunnel": "TUNNEL",
              "encap": "ENCAPSULATED_DATA"}


@dataclass(frozen=True, slots=True)
class Scope:
    messages: frozenset[int] | None = None  # None: any message
    signed: bool = False  # only frames with a signature

    def both(self, other: Scope) -> Scope:
        if self.messages is None or other.messages is None:
            ids = self.messages if other.messages is None else other.messages
        else:
            ids = self.messages & other.messages
        return Scope(ids, self.signed or other.signed)

    def either(self, other: Scope) -> Scope:
        ids = None if self.messages is None or other.messages is None else self.messages | other.messages
        return Scope(ids, self.signed and other.signed)


ANY = Scope()


def _number(text: str) -> int | None:
    try:
        return int(text, 0)
    except ValueError:
        return None


def _ids_of_values(values: tuple[Value | Range | Name, ...], registry: FieldRegistry) -> frozenset[int] | None:
    out: set[int] = set()
    by_name = registry.dialect.by_name
    for v in values:
        if isinstance(v, Range):
            lo, hi = _number(v.lo.text), _number(v.hi.text)
            if lo is None or hi is None or hi - lo > MAX_RANGE:
                return None
            out.update(range(lo, hi + 1))
            continue
        n = _number(v.text)
        if n is not None:
            out.add(n)
            continue
        md = by_name.get(v.text)
        if md is None:
            return None  # (the compiler refuses what it cannot read; nothing is assumed here)
        out.add(md.id)
    return frozenset(out)


def _test(node: Test, registry: FieldRegistry) -> Scope:
    hit = registry.lookup(node.name.text)
    if isinstance(hit, MessageDef):
        return Scope(frozenset({hit.id}))
    if isinstance(hit, PayloadField):
        return Scope(frozenset(hit.defs))
    if not isinstance(hit, Field):
        return ANY
    if hit.name in MESSAGE_FIELDS and node.op in ("==", "in"):
        return Scope(_ids_of_values(node.values, registry))
    if hit.name == "signature" or hit.name.startswith("signature."):
        return Scope(None, True)
    owner = registry.dialect.by_name.get(CONTAINERS.get(hit.name.partition(".")[0], ""))
    return Scope(frozenset({owner.id})) if owner is not None else ANY


def scope_of(node: Node, registry: FieldRegistry) -> Scope:
    """The frames `node` can match."""
    if isinstance(node, Test):
        return _test(node, registry)
    if isinstance(node, Not):
        return ANY
    parts = [scope_of(a, registry) for a in node.args]
    out = parts[0]
    for p in parts[1:]:
        out = out.both(p) if node.op == "&&" else out.either(p)
    return out


def filter_scope(text: str, registry: FieldRegistry) -> Scope:
    """`scope_of` a filter's text (which compiles: the caller compiled it first)."""
    return scope_of(parse(text), registry)
