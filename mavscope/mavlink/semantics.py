"""What MAVLink values mean, written once: coordinate frames, scaled coordinates, enum and command names.

The detail tree, the summaries, missions, commands and the TUI all ask these questions; each answer
lives here so that they cannot drift apart (they once disagreed on which frames are in degrees).
"""

from __future__ import annotations

import math

from mavscope.mavlink import floats
from mavscope.mavlink.dialect import Dialect, MessageDef

# MAV_FRAME values whose x/y are latitude/longitude: the MAV_FRAME_GLOBAL* entries of common.xml
# (a test checks this against the dialect's enum).
GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})
MAV_FRAME_MISSION = 2  # "not a frame": x and y are plain parameters (param5/6), never scaled
# Messages whose x/y are int32 (degrees * 1e7 in a global frame, metres * 1e4 in a local one).
INT_COORDINATE_MESSAGES = frozenset({"COMMAND_INT", "MISSION_ITEM_INT"})
# Messages whose param1..7 (x/y/z as 5..7) take their meaning from the command (MAV_CMD's <param>s).
COMMAND_MESSAGES = frozenset({"COMMAND_LONG", "COMMAND_INT", "MISSION_ITEM", "MISSION_ITEM_INT"})
COMMAND_PARAM_INDEX = {"param1": 1, "param2": 2, "param3": 3, "param4": 4, "param5": 5, "param6": 6, "param7": 7,
                       "x": 5, "y": 6, "z": 7}
DEGE7 = 1e7  # degrees * 1e7 on the wire
LOCAL_INT_SCALE = 1e4  # metres * 1e4 in the *_INT messages' local frames


def is_global(frame: int | None) -> bool:
    return frame in GLOBAL_FRAMES


def int_coordinate(value: int, frame: int | None) -> float:
    """An int32 x/y of COMMAND_INT or MISSION_ITEM_INT in its unit: degrees in a global frame, the plain
    parameter in MAV_FRAME_MISSION, else metres."""
    if frame == MAV_FRAME_MISSION:
        return float(value)
    return value / (DEGE7 if frame in GLOBAL_FRAMES else LOCAL_INT_SCALE)


def coordinate_unit(frame: int | None) -> str:
    """The unit of x/y in `frame`: "deg", "raw" (MAV_FRAME_MISSION: parameters) or "m"."""
    return "deg" if frame in GLOBAL_FRAMES else "raw" if frame == MAV_FRAME_MISSION else "m"


def degrees_text(value: int) -> str:
    """A degE7 value as the tree shows it: "47.3977419° (473977419)"."""
    return f"{value / DEGE7:.7f}° ({value})"


def message_label(msgid: int, msgdef: MessageDef | None) -> str:
    """A message's name, or UNKNOWN_<id> for an id in no loaded dialect: the one spelling everywhere."""
    return msgdef.name if msgdef is not None else f"UNKNOWN_{msgid}"


NAN_TEXT = "NaN"  # how a NaN reads everywhere (PX4 and QGroundControl send it for "unset" / "unchanged")


def float_text(v: float, float32: bool = True) -> str:
    """A float (`float32`: a MAVLink `float` field) or double value as the tree, summaries and tables show
    it: the shortest text that reads back as the same value (mavlink/floats.py: 30.48, not 30.4799995),
    NaN as NAN_TEXT (one spelling everywhere), infinities as `inf` and `-inf`."""
    return NAN_TEXT if math.isnan(v) else repr(v) if math.isinf(v) else floats.float_text(v, float32)


def finite(v: object) -> object:
    """`v`, or None for a NaN or infinite float (PX4 and QGroundControl send NaN for "unchanged")."""
    return None if isinstance(v, float) and (math.isnan(v) or math.isinf(v)) else v


def enum_name(dialect: Dialect, enum: str, value: int) -> str:
    """The entry name of `value` in `enum`, or the number as text where the dialect has none."""
    e = dialect.enums.get(enum)
    name = e.name_of(value) if e is not None else None
    return name or str(value)


MESSAGE_ID_LABELS = frozenset({"Message ID"})  # params whose value is a message id (REQUEST_MESSAGE, intervals)


def command_param_name(dialect: Dialect, command: int, index: int, value: object) -> str | None:
    """The name of a command parameter's value where the XML says what names it: an entry of the enum
    the <param> gives (MAV_BOOL_TRUE), or the message of a "Message ID" (REQUEST_MESSAGE 148 ->
    AUTOPILOT_VERSION); None otherwise (or for a value that is not a whole number)."""
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value != int(value):
        return None  # (NaN and infinities first: int() of an infinity raises)
    n = int(value)
    enum = dialect.command_param_enum(command, index)
    if enum:
        e = dialect.enums.get(enum)
        if e is None:
            return None
        if e.bitmask:
            return " | ".join(e.flags_of(n)) or None
        return e.name_of(n)
    for i, label, _ in dialect.command_params(command):
        if i == index and label in MESSAGE_ID_LABELS:
            md = dialect.messages.get(n)
            return md.name if md is not None else None
    return None


def command_param(dialect: Dialect, message: str, field: str, command: object) -> tuple[str, str] | None:
    """(label, units) that MAV_CMD `command` gives field `field` (param1..7, x, y, z) of a command-carrying
    message, or None."""
    if message not in COMMAND_MESSAGES or not isinstance(command, int):
        return None
    index = COMMAND_PARAM_INDEX.get(field)
    if index is None:
        return None
    for i, label, units in dialect.command_params(command):
        if i == index:
            return label, units
    return None


def holds_nothing(value: object) -> bool:
    """A command parameter's value that says nothing: 0 (or -0.0), or NaN ("no value": JSON's null, None)."""
    return value is None or (isinstance(value, (int, float)) and (value == 0 or value != value))


def param_shown(label: str | None, value: object) -> bool:
    """Whether a command's parameter (param1..7, COMMAND_INT's and MISSION_ITEM*'s x, y, z) is shown, in
    `commands` and the summary lines alike: when its MAV_CMD entry labels it (`label`: the <param>'s label,
    Dialect.command_params), or when it holds something (`holds_nothing`); an unlabelled 0 is left out."""
    return bool(label) or not holds_nothing(value)
