"""`k`: add a signing key or a payload cipher while browsing; the verdicts update when accepted.

The dialog builds what `--key` / `--cipher` take on the command line (docs/security.md) and the app
passes it through the same option parsing, so a key that the command line refuses is refused here,
with the same message. What is typed is masked (someone may be watching the screen, or recording it),
and the error line never shows it: the parser's messages describe a refused spec by its shape only, and
any piece of the typed text is blanked out of the message besides.
"""

from __future__ import annotations

import re

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, RadioButton, RadioSet, Static

from mavscope.tui.widgets.words import Pane, Title

# words of the spec syntax, left in an error message even when they were typed
_SYNTAX = frozenset(("hex", "base64", "passphrase", "qgc", "file", "xor", "aes-128-ctr", "aes-gcm", "ecdh", "iv"))

# (option the text goes to, prefix added to it, radio label, hint under the radios)
KINDS = (
    ("key", "passphrase:", "Signing passphrase (SHA-256, as MAVProxy)", "the passphrase as given to MAVProxy"),
    ("key", "qgc:", "QGroundControl passphrase (PBKDF2)", "the passphrase as typed in QGroundControl"),
    ("key", "hex:", "Signing key in hex", "64 hex digits"),
    ("key", "", "Key spec (as --key)", "[NAME=]hex:… | base64:… | passphrase:… | qgc:… | file:KEYRING.toml"),
    ("cipher", "", "Payload cipher (as --cipher)", "METHOD=SCHEME:KEYSPEC, e.g. 7=xor or 1=aes-128-ctr:hex:…"),
)


class KeyDialog(ModalScreen[None]):
    BINDINGS = [Binding("escape", "dismiss", "Cancel")]
    DEFAULT_CSS = """
    KeyDialog { align: center middle; }
    KeyDialog > Vertical { width: 80; max-width: 95%; height: auto; border: thick $primary;
                           background: $surface; padding: 1 2; }
    KeyDialog RadioSet { width: 100%; border: none; margin-bottom: 1; }
    KeyDialog #key-help { color: $text-muted; margin-bottom: 1; }
    KeyDialog #key-error { color: $error; height: auto; }
    KeyDialog Horizontal { height: auto; align-horizontal: right; margin-top: 1; }
    KeyDialog Button { margin-left: 2; }
    """

    def compose(self) -> ComposeResult:
        with Vertical() as v:
            v.border_title = "Add key material"
            with RadioSet(id="key-kind"):
                for i, kind in enumerate(KINDS):
                    yield RadioButton(kind[2], value=i == 0, id=f"kind-{i}")
            yield Title(KINDS[0][3], id="key-help")
            yield Input(placeholder="key", id="key-input", password=True)
            yield Pane("", id="key-error")
            with Horizontal():  # Add first: Tab from the input lands on it, not on Cancel (which loses the key)
                yield Button("Add", variant="primary", id="key-add")
                yield Button("Cancel", id="key-cancel")

    def on_mount(self) -> None:
        self.query_one("#key-input", Input).focus()

    @property
    def kind(self) -> tuple[str, str, str, str]:
        return KINDS[max(0, self.query_one(RadioSet).pressed_index)]

    def on_radio_set_changed(self, event: RadioSet.Changed) -> None:
        self.query_one("#key-help", Label).update(KINDS[max(0, event.index)][3])
        self.query_one("#key-input", Input).focus()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        self.submit()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "key-add":
            self.submit()
        else:
            self.dismiss(None)

    def submit(self) -> None:
        text = self.query_one("#key-input", Input).value.strip()
        error = self.query_one("#key-error", Static)
        if not text:
            error.update("enter a key first")
            return
        option, prefix, _, _ = self.kind
        problem = self.app.add_key(option, prefix + text)  # type: ignore[attr-defined]
        if problem:
            error.update(redact(problem, text))
            return
        self.dismiss(None)


def redact(message: str, typed: str) -> str:
    """`message` without the typed text or any piece of it (split at ':' and '=') that may be a secret."""
    pieces = {typed} | {p for p in re.split(r"[:=]", typed) if len(p) >= 3 and p.lower() not in _SYNTAX}
    for piece in sorted(pieces, key=len, reverse=True):
        if piece:
            message = message.replace(piece, "•••")
    return message
