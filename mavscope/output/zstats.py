"""`read -z SPEC` (and `-q` for nothing else): statistics after the frames, with tshark's `-z` spellings.

Computed by the analyses `mavscope stats` runs (StatsBuilder over column batches, the expert's detectors),
over every frame of the capture, as tshark's statistics see every packet whatever `-Y` shows; printed in
tshark's layouts, counting MAVLink frames and their bytes on the wire (tshark counts packets and their
link-layer bytes: on a capture of one MAVLink frame per datagram the frame counts agree).

- `io,stat,INTERVAL[,FILTER...]`: frames and bytes per INTERVAL seconds from the first record, one column
  per FILTER (a display filter; all frames without one);
- `conv,udp`, `conv,tcp`: conversations (endpoint pairs), frames and bytes each way, start, duration;
- `endpoints,udp`, `endpoints,tcp`: per endpoint, frames and bytes in all, sent and received;
- `expert`: the frames' notes by severity and code, with counts, then the findings (`stats`' expert);
- `mavlink,msgs`, `mavlink,links`, `mavlink,signing`: MAVLink's own: messages with rates, links with
  loss, signature verdicts per link.

Every text from a capture or a dialect is escaped (visible).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import IO

from mavscope.analysis import expert_batch
from mavscope.analysis.expert import Expert
from mavscope.analysis.stats import BATCH, StatsBuilder
from mavscope.errors import UsageError
from mavscope.filter import compile_filter
from mavscope.filter.compiler import DisplayFilter
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.notes import Finding, Severity
from mavscope.pipeline.batch import FrameBatch, Tables
from mavscope.visible import visible

KINDS = ("io,stat", "conv,udp", "conv,tcp", "endpoints,udp", "endpoints,tcp", "expert", "mavlink,msgs",
         "mavlink,links", "mavlink,signing")
RULE = "=" * 80


@dataclass
class _Io:
    interval: float
    filters: list[DisplayFilter | None]
    frames: list[Counter[int]] = field(default_factory=list)
    nbytes: list[Counter[int]] = field(default_factory=list)


def parse_specs(specs: Sequence[str], dialect: Dialect) -> list[tuple[str, _Io | None]]:
    """The `-z` specs (UsageError or FilterError for a wrong one), each with its io,stat state."""
    out: list[tuple[str, _Io | None]] = []
    for spec in specs:
        if spec.startswith("io,stat,"):
            interval_text, *filters = spec[len("io,stat,"):].split(",")
            try:
                interval = float(interval_text)
            except ValueError:
                interval = math.nan
            if not (interval > 0 and math.isfinite(interval)):
                raise UsageError(f"-z {visible(spec)}: io,stat,INTERVAL[,FILTER...] needs an interval in seconds > 0")
            flts = [compile_filter(f, dialect) if f.strip() else None for f in filters] or [None]
            io = _Io(interval, flts, [Counter() for _ in flts], [Counter() for _ in flts])
            out.append(("io,stat", io))
        elif spec in KINDS:
            out.append((spec, None))
        else:
            raise UsageError(f"-z {visible(spec)}: one of io,stat,INTERVAL[,FILTER...], {', '.join(KINDS[1:])}")
    return out


class ZStats:
    """Fed every frame (`frame`), then `write` prints each statistic asked for, in order."""

    def __init__(self, specs: Sequence[str], dialect: Dialect, t0: float | None) -> None:
        self.specs = parse_specs(specs, dialect)
        self.t0 = t0
        self.dialect = dialect
        self.builder = StatsBuilder()
        self.expert = Expert(dialect)
        self.tables = Tables()
        self.chunk: list[Frame] = []
        self.notes: Counter[tuple[Severity, str, str]] = Counter()
        self.first: float | None = None
        self.last: float | None = None
        self.ios = [io for _, io in self.specs if io is not None]

    def frame(self, f: Frame) -> None:
        self.chunk.append(f)
        if len(self.chunk) == BATCH:
            self._flush()
        for n in f.notes:
            self.notes[(n.severity, n.code, f.msgname or f"message {f.msgid}")] += 1
        t = f.time
        if t is not None:
            self.first = t if self.first is None else self.first
            self.last = t
        if self.ios and t is not None and self.t0 is not None:
            fields = None
            for io in self.ios:
                k = int((t - self.t0) // io.interval)
                for col, flt in enumerate(io.filters):
                    if flt is None or flt.matches(f, fields):
                        io.frames[col][k] += 1
                        io.nbytes[col][k] += len(f.raw)

    def _flush(self) -> None:
        if self.chunk:
            b = FrameBatch.of_frames(self.chunk, self.tables)
            expert_batch.feed(self.expert, b, self.builder.add_batch(b))
            self.chunk = []

    def write(self, out: IO[str]) -> None:
        self._flush()
        stats = self.builder.result()
        stats.logged_in_part = self.expert.logged_in_part()
        doc = stats.to_json()
        writers = {"conv,udp": lambda: self._conv(out, doc, "udp"), "conv,tcp": lambda: self._conv(out, doc, "tcp"),
                   "endpoints,udp": lambda: self._endpoints(out, doc, "udp"),
                   "endpoints,tcp": lambda: self._endpoints(out, doc, "tcp"),
                   "expert": lambda: self._expert(out, self.expert.findings()),
                   "mavlink,msgs": lambda: self._msgs(out, doc), "mavlink,links": lambda: self._links(out, doc),
                   "mavlink,signing": lambda: self._signing(out, doc)}
        for kind, io in self.specs:
            if io is not None:
                self._io(out, io)
            else:
                writers[kind]()

    def _duration(self) -> float:
        return 0.0 if self.first is None or self.last is None else self.last - self.first

    def _io(self, out: IO[str], io: _Io) -> None:
        dur = (self.last - self.t0) if self.last is not None and self.t0 is not None else 0.0
        buckets = max(1, int(dur // io.interval) + 1)
        names = [visible(f.text) if f is not None else "Frames and bytes" for f in io.filters]
        lines = [f"Duration: {self._duration():.6f} secs", f"Interval: {io.interval:g} secs", ""]
        lines += [f"Col {k + 1}: {n}" for k, n in enumerate(names)]
        rows = []
        for b in range(buckets):
            lo, hi = b * io.interval, (b + 1) * io.interval
            label = f"{lo:g} <> {hi:g}" if b < buckets - 1 else f"{lo:g} <> Dur"
            rows.append([label] + [x for c in range(len(names)) for x in (str(io.frames[c][b]), str(io.nbytes[c][b]))])
        head = ["Interval"] + [x for _ in names for x in ("Frames", "Bytes")]
        widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
        out.write("\n" + RULE + "\nIO Statistics (MAVLink frames)\n")
        out.write("\n".join(lines) + "\n\n")
        out.write(" | ".join(h.rjust(w) for h, w in zip(head, widths)) + "\n")
        for r in rows:
            out.write(" | ".join(c.rjust(w) for c, w in zip(r, widths)) + "\n")
        out.write(RULE + "\n")

    def _conv(self, out: IO[str], doc: dict, transport: str) -> None:
        out.write(f"{RULE}\n{transport.upper()} Conversations (MAVLink frames)\nFilter:<No Filter>\n")
        out.write(f"{'':54}|       <-      | |       ->      | |     Total     |    Relative    |   Duration   |\n")
        out.write(f"{'':54}| Frames  Bytes | | Frames  Bytes | | Frames  Bytes |      Start     |              |\n")
        for c in doc["conversations"]:
            if c["transport"] != transport:
                continue
            start = c["start"] - self.t0 if c["start"] is not None and self.t0 is not None else 0.0
            pair = f"{visible(c['a']):26} <-> {visible(c['b']):23}"
            out.write(f"{pair} {c['frames_b_to_a']:>8} {c['bytes_b_to_a']:>6}  {c['frames_a_to_b']:>8} "
                      f"{c['bytes_a_to_b']:>6}  {c['frames']:>8} {c['bytes']:>6}  {start:>15.9f} "
                      f"{(c['duration'] or 0.0):>13.4f}\n")
        out.write(RULE + "\n")

    def _endpoints(self, out: IO[str], doc: dict, transport: str) -> None:
        ends: dict[str, list[int]] = {}  # endpoint -> frames, bytes, tx frames, tx bytes, rx frames, rx bytes
        for c in doc["conversations"]:
            if c["transport"] != transport:
                continue
            for me, tx, txb, rx, rxb in ((c["a"], c["frames_a_to_b"], c["bytes_a_to_b"], c["frames_b_to_a"],
                                          c["bytes_b_to_a"]),
                                         (c["b"], c["frames_b_to_a"], c["bytes_b_to_a"], c["frames_a_to_b"],
                                          c["bytes_a_to_b"])):
                if not me:
                    continue
                e = ends.setdefault(me, [0] * 6)
                for k, v in enumerate((tx + rx, txb + rxb, tx, txb, rx, rxb)):
                    e[k] += v
        out.write(f"{RULE}\n{transport.upper()} Endpoints (MAVLink frames)\nFilter:<No Filter>\n")
        out.write("                       |  Port  ||  Packets  | |  Bytes  | | Tx Packets | | Tx Bytes | "
                  "| Rx Packets | | Rx Bytes |\n")
        for me, e in sorted(ends.items(), key=lambda kv: (-kv[1][0], kv[0])):
            addr, _, port = me.rpartition(":")
            out.write(f"{visible(addr):25} {port:>5} {e[0]:>10} {e[1]:>13} {e[2]:>10} {e[3]:>15} {e[4]:>10} "
                      f"{e[5]:>13}\n")
        out.write(RULE + "\n")

    def _expert(self, out: IO[str], findings: list[Finding]) -> None:
        out.write(f"{RULE}\nExpert information (notes of the frames; findings of `mavscope stats`)\n")
        for sev in sorted({s for s, _, _ in self.notes}, key=lambda s: -s.rank):
            group = [(k, n) for k, n in self.notes.items() if k[0] is sev]
            out.write(f"\n{sev.value.capitalize()}s ({sum(n for _, n in group)})\n")
            out.write("=" * len(f"{sev.value}s (x)") + "\n")
            for (_, code, msg), n in sorted(group, key=lambda kv: (-kv[1], kv[0][1], kv[0][2])):
                out.write(f"  {n:>10}  {code:<28} {visible(msg)}\n")
        if findings:
            out.write(f"\nFindings ({len(findings)})\n")
            for f in findings:
                out.write(f"  {f.severity.value:<5} {f.code:<28} {visible(f.message)}\n")
        out.write(RULE + "\n")

    def _msgs(self, out: IO[str], doc: dict) -> None:
        out.write(f"{RULE}\nMAVLink messages\n")
        out.write(f"{'sysid/compid':>12}  {'message':<32} {'count':>8} {'rate Hz':>9} {'bytes':>10}\n")
        for m in doc["messages"]:
            rate = "burst" if m["burst"] else "-" if m["rate_hz"] is None else f"{m['rate_hz']:.2f}"
            out.write(f"{m['sysid']:>8}/{m['compid']:<3}  {visible(m['msgname']):<32} {m['count']:>8} {rate:>9} "
                      f"{m['bytes']:>10}\n")
        out.write(RULE + "\n")

    def _links(self, out: IO[str], doc: dict) -> None:
        out.write(f"{RULE}\nMAVLink links (sysid, compid)\n")
        out.write(f"{'sysid/compid':>12}  {'received':>9} {'lost':>7} {'loss %':>7} {'dup':>5} {'late':>5}\n")
        for lk in doc["links"]:
            mark = "*" if lk["logged_in_part"] else ""
            pct = "-" if lk["loss_pct"] is None else f"{lk['loss_pct']:.2f}"
            out.write(f"{lk['sysid']:>8}/{lk['compid']:<3}  {lk['received']:>9} {lk['lost']:>6}{mark:1} "
                      f"{pct:>7} {lk['duplicates']:>5} {lk['reordered']:>5}\n")
        if any(lk["logged_in_part"] for lk in doc["links"]):
            out.write("* logged only in part (a ground station's own frames in its tlog): not link loss\n")
        out.write(RULE + "\n")

    def _signing(self, out: IO[str], doc: dict) -> None:
        out.write(f"{RULE}\nMAVLink signing per link (signature verdicts)\n")
        for lk in doc["links"]:
            verdicts = ", ".join(f"{k} {v}" for k, v in sorted(lk["signature"].items()))
            out.write(f"{lk['sysid']:>8}/{lk['compid']:<3}  {verdicts}\n")
        out.write(RULE + "\n")
