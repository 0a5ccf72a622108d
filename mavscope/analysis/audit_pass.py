"""`audit`'s findings, one implementation for every output that reports them (`mavscope audit`, so
`batch -- audit`, and the export's findings table, source `audit`: mavscope.export).

What the audit adds to the security stage's verdicts, in one pass (`AuditPass.add` per frame, in capture
order): their summary (mavscope.security.audit), the unsigned and v1 frames of signing senders judged with
the whole capture (mavscope.security.downgrade: an unsigned command placed before its sender's first signed
frame is a finding as one placed after it), and the commands the command matcher gave up (its bound hides
a command's answer); `result(expert)` at the end merges them with every security and capacity finding of
the expert's detectors, the pass `stats` runs (a code both report, `replay`, `key-leak`, `hidden-frame`, is
given once, as the expert words it, as `stats` shows it). With `rules` (a mavscope.rules RuleSet: the shipped
pack, the user's), each frame is judged by the detection rules too, their findings (code `rule`, each with
its rule id) among the audit's own.
"""

from __future__ import annotations

from collections.abc import Iterable

from mavscope.analysis.command_log import CommandMatcher, feed_command
from mavscope.analysis.events import EventLog
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.notes import CODES, Finding, Group, sort_findings
from mavscope.pipeline.dissect import Anomaly
from mavscope.rules import RuleEngine, RuleSet
from mavscope.security.audit import Audit
from mavscope.security.downgrade import Downgrades
from mavscope.security.keystream import Recovery


def merged(expert: list[Finding], own: list[Finding]) -> list[Finding]:
    """The expert's security findings and the audit's own, a code both give once (the expert's); and every
    `capacity` finding (what a bound of an analysis gave up: each its own, docs/security.md, "Bounds")."""
    security = [f for f in expert if CODES[f.code].group in (Group.SECURITY, Group.CAPACITY)]
    codes = {f.code for f in security if CODES[f.code].group is Group.SECURITY}
    return sort_findings(security + [f for f in own if f.code not in codes])


class AuditPass:
    """The audit's own analyses over a capture: `anomaly(item)` and `add(frame)` in capture order, then
    `result(expert_findings)`. A caller that feeds frames in bulk (the export's native source) gives each
    part what `add` would: `audit`, `downgrades`, and `command(frame)` for the command messages."""

    def __init__(self, dialect: Dialect, *, story: bool = False, rules: RuleSet | None = None) -> None:
        self.audit = Audit()
        self.downgrades = Downgrades()
        self.matcher = CommandMatcher(dialect)  # `commands`' matching: what its bound gives up hides an answer
        # `story`: the flight's story too (`events`, and through it `mission`), for what its bounds give up (a
        # flood that hides an arming, a command or an upload from those lists is said; `audit` runs it)
        self.story = EventLog(dialect) if story else None
        # the detection rules, reading the vehicles' HEARTBEAT state from the event log's Systems when it runs
        self.rules = None if rules is None else RuleEngine(rules, self.story.systems if self.story else None)

    def anomaly(self, item: Anomaly) -> None:
        """A record's notes that belong to no frame."""
        self.audit.anomaly(item)

    def add(self, f: Frame, fields: dict[str, object] | None = None) -> None:
        """Frame `f`; `fields`: its payload where the caller decoded it already (Expert.add's: decoded once)."""
        self.audit.add(f)
        self.downgrades.add(f)
        self.command(f, fields)
        if self.rules is not None:
            self.rules.add(f, fields)
        if self.story is not None:
            self.story.add(f)

    def command(self, f: Frame, fields: dict[str, object] | None = None) -> None:
        """A frame to the command matcher, if it is a command or an ACK (command_log.feed_command)."""
        feed_command(self.matcher, f, fields)

    def result(self, expert: list[Finding], *, words: Iterable[bytes] | None = None, qgc: bool = False,
               known: Iterable[tuple[int, bytes]] = ()) -> tuple[list[Finding], list[Recovery]]:
        """`audit`'s findings, most severe first, with `expert` (the expert's findings of the same capture),
        and the payloads recovered without a key."""
        own, recoveries = self.audit.result(words=words, qgc=qgc, known=known, early=self.downgrades.judged())
        gave_up = self.matcher.given_up.finding()
        own += [gave_up] if gave_up is not None else []
        if self.rules is not None:
            own += self.rules.findings()
        if self.story is not None:
            own += [f for f in self.story.finish().capacity if f not in own]  # (its command matcher's is ours)
        return merged(expert, own), recoveries
