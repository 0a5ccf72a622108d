"""The tshark options `read` and `live` share: `-T fields` with `-e` and `-E`, and `-z` statistics.

One definition of each option and of what may go with what (`check`), so both commands spell them as
tshark does and refuse the same mistakes (docs/tshark.md)."""

from __future__ import annotations

import argparse

from mavscope.errors import UsageError

ZSTATS_HELP = ("statistics after the frames, as tshark's -z: io,stat,INTERVAL[,FILTER...], conv,udp, conv,tcp, "
               "endpoints,udp, endpoints,tcp, expert, mavlink,msgs, mavlink,links, mavlink,signing "
               "(repeatable; -q: only them)")


def add_fields_options(p: argparse.ArgumentParser) -> None:
    """-e FIELD and -E OPTION=VALUE (for `-T fields`)."""
    p.add_argument("-e", dest="fields", action="append", default=[], metavar="FIELD",
                   help="with -T fields: a field to print (any registry name, e.g. mavlink.seq, ATTITUDE.roll, "
                        "mavlink_proto.sysid); repeat for more columns")
    p.add_argument("-E", dest="field_options", action="append", default=[], metavar="OPTION=VALUE",
                   help="with -T fields: header=y|n, separator=/t|/s|C, quote=d|s|n, occurrence=f|l|a, "
                        "aggregator=/s|C (as tshark's -E)")


def add_statistics_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("-z", dest="statistics", action="append", default=[], metavar="STAT", help=ZSTATS_HELP)


def check(args: argparse.Namespace, command: str, stdout_records: bool) -> None:
    """What tshark refuses: -e or -E without -T fields, -T fields without -e, and -z when standard output
    takes the records (`stdout_records`: -w -)."""
    if (args.fields or args.field_options) and args.format != "fields":
        raise UsageError(f'{command}: -e and -E are for -T fields (tshark: "-e" was specified, but the output '
                         'format is not "fields")')
    if args.format == "fields" and not args.fields:
        raise UsageError(f"{command}: -T fields prints the fields named with -e FIELD: name at least one")
    if args.statistics and stdout_records:
        raise UsageError(f"{command}: -z prints on standard output, where -w - writes the records: write them to "
                         "a file")
