"""What the parameter analysis reports: the timeline (`ParamChange`: a set, or a value that changed),
each component's parameters, and the log of a capture."""

from __future__ import annotations

from dataclasses import dataclass, field

from mavscope.analysis.params.values import Value
from mavscope.mavlink.frame import Addr
from mavscope.notes import Finding


@dataclass(frozen=True, slots=True)
class ParamChange:
    """One event of the timeline: a request to set a parameter (`kind` "set": PARAM_SET, PARAM_EXT_SET),
    or a component reporting a value other than the one it reported before that no set in the capture
    answers (`kind` "change": PARAM_VALUE, PARAM_EXT_VALUE, a param.pck read over FTP). A change that
    another message explains (a stream rate REQUEST_DATA_STREAM set: `streams.py`) says so in
    `explanation`, with that message's frame in `cause_frame`; a change without one is unexplained."""

    time: float | None
    frame: int
    kind: str  # "set" or "change"
    source: str  # PARAM_SET, PARAM_EXT_SET, PARAM_VALUE, PARAM_EXT_VALUE, "FTP <path>"
    sender: Addr  # who sent the frame
    component: Addr  # whose parameter (a set's target; a report's sender)
    name: str
    value: Value
    previous: Value | None  # the value known before (None: not known)
    type: int | None  # MAV_PARAM_TYPE (MAV_PARAM_EXT_TYPE for PARAM_EXT_*)
    link: str  # the sender's network address, or the capture's transport (tlog, raw)
    signature: str  # the frame's signature verdict: unsigned, valid, invalid, no-key, replay
    confirmed: bool | None  # sets: the component reported the value set (True), another one (False), nothing
    confirm_frame: int | None  # the report (PARAM_VALUE, PARAM_EXT_ACK) that answered a set
    reported: Value | None  # the value that report carried
    retries: int  # sets: the same set sent again before an answer
    security: str | None  # the parameter's security category (mavscope.analysis.params.security)
    disables: str | None  # what this value turns off, if anything
    ack: str | None = None  # PARAM_EXT_SET: the PARAM_EXT_ACK result name
    confirm_time: float | None = None  # capture time of `confirm_frame`
    cause_frame: int | None = None  # changes: the frame of the message that explains it
    explanation: str | None = None  # changes: what explains it ("set by REQUEST_DATA_STREAM frame N")


@dataclass
class Param:
    """A component's parameter as last reported."""

    value: Value
    type: int | None
    source: str
    first_frame: int
    last_frame: int
    reports: int = 1
    changes: int = 0
    default: Value | None = None


@dataclass
class Component:
    addr: Addr
    params: dict[str, Param] = field(default_factory=dict)
    encoding: str | None = None  # how its PARAM_VALUE carries integers (c-cast, bytewise)
    encoding_basis: str = ""  # AUTOPILOT_VERSION, HEARTBEAT, values
    announced: int | None = None  # the last param_count it sent
    sources: dict[str, int] = field(default_factory=dict)  # source -> values reported


@dataclass
class ParamLog:
    components: list[Component]
    timeline: list[ParamChange]
    main: Addr | None  # the component whose parameters make `final`
    ftp: list[dict[str, object]]  # the param.pck files read over FTP and what they held
    findings: list[Finding] = field(default_factory=list)
    given_up: dict[str, int] = field(default_factory=dict)

    @property
    def final(self) -> dict[str, Value]:
        comp = next((c for c in self.components if c.addr == self.main), None)
        return {} if comp is None else {n: p.value for n, p in sorted(comp.params.items())}

    def component(self, addr: Addr) -> Component | None:
        return next((c for c in self.components if c.addr == addr), None)
