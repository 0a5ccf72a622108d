"""Every key of the TUI, in one table: the help screen, docs/tui.md and the README show this."""

from __future__ import annotations

# (keys, what they do, where they work)
KEYS: tuple[tuple[str, str, str], ...] = (
    ("Up / Down", "previous / next frame", "packet list"),
    ("PageUp / PageDown", "one page up / down", "packet list"),
    ("Home / End", "first / last frame", "packet list"),
    ("Enter", "open the frame's detail tree (focus moves to the tree)", "packet list"),
    ("Up / Down, Left / Right", "move in the tree; Left / Right fold and unfold", "detail tree"),
    ("Arrows", "move the byte cursor: the field holding the byte is selected in the tree", "hex pane"),
    ("Tab / Shift+Tab", "cycle the panes: packet list, detail tree, hex", "everywhere"),
    ("/", "edit the display filter", "everywhere"),
    ("Enter", "apply the filter (empty: show every frame)", "filter bar"),
    ("Escape", "leave the filter bar (the filter stays applied)", "filter bar"),
    ("s", "statistics: message rates with sparklines, loss per link", "everywhere"),
    ("m", "mission: waypoint table and a plot of the track", "everywhere"),
    ("o", "objects: files (MAVLink FTP), logs and images moved over the link", "everywhere"),
    ("e", "expert findings", "everywhere"),
    ("v", "events: the flight's story; Enter jumps to the event's frame", "everywhere"),
    ("p", "plot the field selected in the detail tree over time (min to max per interval)", "everywhere"),
    ("k", "add a signing key or a cipher key (verdicts update)", "everywhere"),
    ("?", "this help", "everywhere"),
    ("Escape / q", "close a screen or dialog", "screens"),
    ("q", "quit", "main screen"),
    ("Ctrl+C", "quit", "everywhere"),
    ("Mouse", "click a frame, a tree node or a byte; wheel scrolls; double click opens the tree", "everywhere"),
)
