"""What the analysis commands (stats, mission, commands, timeline) share: their options and reading
every frame of the capture through `capture_session` (so -Y and every other stage apply)."""

from __future__ import annotations

import argparse

from mavscope.cli import Env
from mavscope.commands.common import (
    add_capture_options,
    add_filter_option,
    add_key_options,
    capture_session,
    report_anomaly,
)
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.pipeline.dissect import Anomaly


def add_analysis_options(p: argparse.ArgumentParser) -> None:
    add_capture_options(p)
    add_filter_option(p)
    add_key_options(p)  # signature and encryption verdicts for filters, statistics and findings
    p.add_argument("--json", action="store_true", help="write one JSON document to stdout (docs/analysis.md)")


def read_frames(args: argparse.Namespace, env: Env) -> tuple[list[Frame], Dialect, str]:
    """Every frame the session shows, in capture order; anomalies go to stderr as `read` reports them."""
    frames: list[Frame] = []
    with capture_session(args, env) as session:
        for item in session.shown():
            if type(item) is Anomaly:
                report_anomaly(env, session.path, item)
            else:
                frames.append(item)
        return frames, session.dialect, session.path
