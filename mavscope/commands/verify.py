"""`mavscope verify FILE --key ...`: signature verdicts per stream; exit 1 on any invalid, replayed or
injected unsigned frame (a gate for CI pipelines and flight-log intake)."""

from __future__ import annotations

import argparse
from collections import defaultdict
from dataclasses import dataclass, field

from mavscope.cli import Env, ExitStatus
from mavscope.commands.common import add_capture_options, add_key_options, capture_session
from mavscope.dissect import Anomaly
from mavscope.errors import UsageError
from mavscope.mavlink.frame import SignatureStatus

SHOWN = 20


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("verify", help="verify the signatures of a capture; exit 1 on invalid, replayed or "
                                      "injected frames",
                       description="Check every signed frame against the supplied keys (docs/security.md). "
                                   "Exit status: 0 every check passed, 1 an invalid, replayed or injected "
                                   "unsigned frame, 2 bad usage or an unreadable file.")
    add_capture_options(p)
    add_key_options(p)
    p.add_argument("--json", action="store_true", help="print the per-stream table as JSON")
    p.set_defaults(run=run)


@dataclass
class Row:
    links: set[int] = field(default_factory=set)
    frames: int = 0
    signed: int = 0
    valid: int = 0
    invalid: int = 0
    replay: int = 0
    no_key: int = 0
    unsigned: int = 0
    injected: int = 0  # unsigned-in-signed-stream
    keys: set[str] = field(default_factory=set)
    skew: list[float] = field(default_factory=list)  # signature - capture time of each new stream

    def to_json(self, sysid: int, compid: int) -> dict[str, object]:
        return {"sysid": sysid, "compid": compid, "links": sorted(self.links), "frames": self.frames,
                "signed": self.signed, "valid": self.valid, "invalid": self.invalid, "replay": self.replay,
                "no_key": self.no_key, "unsigned": self.unsigned, "unsigned_in_signed_stream": self.injected,
                "keys": sorted(self.keys)}


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    if not (args.key or args.ecdh_private or args.use_leaked_keys or env.environ.get("MAVSCOPE_KEYRING")):
        raise UsageError("verify: no key material: give --key (or --ecdh-private, --use-leaked-keys, "
                         "MAVSCOPE_KEYRING)")
    rows: dict[tuple[int, int], Row] = defaultdict(Row)
    bad: list[tuple[int, str]] = []
    with capture_session(args, env) as session:
        for item in session.items:
            if type(item) is Anomaly:
                continue
            f = item
            row = rows[(f.sysid, f.compid)]
            row.frames += 1
            sec = f.security
            status = sec.signature_status if sec is not None else None
            if f.signature is not None:
                row.signed += 1
                row.links.add(f.signature.link_id)
                if status is SignatureStatus.VALID:
                    row.valid += 1
                elif status is SignatureStatus.INVALID:
                    row.invalid += 1
                    bad.append((f.record, f"invalid signature ({f.msgname or f.msgid} from {f.sysid}/{f.compid})"))
                elif status is SignatureStatus.REPLAY:
                    row.replay += 1
                    bad.append((f.record, f"replay ({f.msgname or f.msgid} from {f.sysid}/{f.compid}, link "
                                          f"{f.signature.link_id})"))
                else:
                    row.no_key += 1
                if sec is not None and sec.key:
                    row.keys.add(sec.key)
                if sec is not None and sec.reason.startswith("first frame") and f.time is not None:
                    row.skew.append(f.signature.unix_time - f.time)
            else:
                row.unsigned += 1
                if any(n.code == "unsigned-in-signed-stream" for n in f.notes):
                    row.injected += 1
                    bad.append((f.record, f"unsigned {f.msgname or f.msgid} from {f.sysid}/{f.compid}, which "
                                          "signs its frames"))
            for n in f.notes:
                if n.code == "key-leak":
                    bad.append((f.record, "SETUP_SIGNING: signing key sent in clear"))
        path = session.path
    failed = any(r.invalid or r.replay or r.injected for r in rows.values())
    if args.json:
        from mavscope.output.tables import write_json

        write_json(env, {"file": path, "ok": not failed,
                         "streams": [rows[k].to_json(*k) for k in sorted(rows)],
                         "problems": [{"frame": r, "message": m} for r, m in bad]})
        return ExitStatus.FINDINGS if failed else ExitStatus.OK
    from rich.table import Table

    from mavscope.output.tables import console

    con = console(env)
    t = Table(title=f"Signatures ({path})", title_justify="left")
    for col in ("sysid/compid", "links", "frames", "signed", "valid", "invalid", "replay", "no-key", "unsigned",
                "injected", "keys", "skew s"):
        t.add_column(col, justify="left" if col in ("links", "keys") else "right")
    for (sysid, compid), r in sorted(rows.items()):
        skew = (f"{min(r.skew):+.3f}" + (f"..{max(r.skew):+.3f}" if len(r.skew) > 1 else "")) if r.skew else "-"
        t.add_row(f"{sysid}/{compid}", ",".join(map(str, sorted(r.links))) or "-", str(r.frames), str(r.signed),
                  str(r.valid), str(r.invalid), str(r.replay), str(r.no_key), str(r.unsigned), str(r.injected),
                  ",".join(sorted(r.keys)) or "-", skew)
    con.print(t)
    for record, message in bad[:SHOWN]:
        con.print(f"frame {record}: {message}", highlight=False)
    if len(bad) > SHOWN:
        con.print(f"... and {len(bad) - SHOWN} more", highlight=False)
    con.print("FAIL: invalid, replayed or injected frames" if failed else "OK: every signed frame verified"
              if all(r.no_key == 0 for r in rows.values()) else "OK: no invalid, replayed or injected frame "
              "(some signed frames had no key)", highlight=False)
    return ExitStatus.FINDINGS if failed else ExitStatus.OK
