"""File names for objects: one safe path component per object, whatever path the vehicle (or an
attacker) put in the frames.

The vehicle path is flattened ("/APM/scripts/a.lua" -> "APM_scripts_a.lua"), every character outside
a small set becomes "_", and the name is prefixed with the object's number, so it is unique, never "."
or "..", never hidden, never absolute and never holds a separator: written into a directory it cannot
land anywhere else. Paths that try to climb out (".." components), hold NUL or control characters, or are
very long are reported (`unsafe_reasons`): a server does not send such paths by accident.
"""

from __future__ import annotations

import hashlib
import re

MAX_COMPONENT = 96  # characters of the flattened path kept in a file name
MAX_VEHICLE_PATH = 255  # longer vehicle paths are reported as unsafe
_UNSAFE = re.compile(r"[^A-Za-z0-9._@=+,~-]")
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


def unsafe_reasons(path: str) -> list[str]:
    """Why a vehicle path could not be used as it is (empty: it could)."""
    reasons = []
    parts = re.split(r"[/\\]", path)
    if ".." in parts:
        reasons.append("a '..' component")
    if "\x00" in path:
        reasons.append("a NUL byte")
    elif _CONTROL.search(path):
        reasons.append("control characters")
    if "\\" in path:
        reasons.append("a backslash (or bytes that are not UTF-8, shown escaped)")
    if len(path.encode("utf-8", "backslashreplace")) > MAX_VEHICLE_PATH:
        reasons.append(f"more than {MAX_VEHICLE_PATH} bytes")
    return reasons


def flatten(text: str) -> str:
    """`text` as one safe file name component (never empty, never starting with '.')."""
    flat = _UNSAFE.sub("_", text.replace("/", "_")).strip("._")
    flat = re.sub(r"_{2,}", "_", flat)
    if len(flat) > MAX_COMPONENT:
        digest = hashlib.sha256(text.encode("utf-8", "backslashreplace")).hexdigest()[:8]
        half = (MAX_COMPONENT - 10) // 2
        flat = f"{flat[:half]}~{digest}~{flat[-half:]}"
    return flat or "object"


def file_name(number: int, label: str, extension: str = "") -> str:
    """The object's file name: its number, its flattened label, an extension. A query string moves before
    the path's own extension ("@PARAM/param.pck?withdefaults=1" -> "@PARAM_param_withdefaults=1.pck")."""
    base, sep, query = label.partition("?")
    head, slash, last = base.rpartition("/")
    stem, dot, ext = last.rpartition(".")
    if sep and dot and stem and ext and len(ext) <= 8 and not extension:
        label, extension = f"{head}{slash}{stem}_{query}", "." + flatten(ext)
    return f"{number:04d}-{flatten(label)}{extension}"


def is_plain_name(name: str) -> bool:
    """Whether `name` is one path component an output directory can hold as is."""
    return bool(name) and name not in (".", "..") and not name.startswith(".") and _UNSAFE.search(name) is None
