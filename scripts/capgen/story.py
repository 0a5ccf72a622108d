"""The simulated flight: keyframes of a vehicle's position, the events of a session (mission upload,
arm, reposition, RTL, landing), and the vehicle's state at any moment, interpolated without libm so that
every platform computes the same telemetry."""

from __future__ import annotations

from dataclasses import dataclass

from .constants import (
    HOME_LAT_DEG,
    HOME_LON_DEG,
    M_PER_DEG_LAT,
    M_PER_DEG_LON,
    MAV_SEVERITY_INFO,
    MAV_SEVERITY_WARNING,
)


@dataclass(frozen=True)
class Keyframe:
    """Where the vehicle is at time `t`; between keyframes it moves in a straight line."""

    t: float  # seconds since the capture start
    north: float  # metres from home
    east: float
    alt: float  # metres above home
    heading: float  # degrees


@dataclass(frozen=True)
class Story:
    """What happens in a session. Times in seconds from the capture start; None = does not happen."""

    duration: float
    keyframes: tuple[Keyframe, ...]
    mission_at: float | None = None
    arm_at: float | None = None
    reposition_at: float | None = None
    rtl_at: float | None = None
    landed_at: float | None = None
    statustexts: tuple[tuple[float, int, str], ...] = ()
    waypoints: tuple[tuple[float, float, float], ...] = ()  # (north, east, alt) of the mission's two WPs
    reposition_to: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class VehicleState:
    """What the telemetry reports at one moment."""

    lat: int  # degE7
    lon: int
    rel_alt: float  # m above home
    vn: float  # m/s
    ve: float
    vd: float
    heading: float  # deg
    armed: bool
    mode: str  # key of PX4_MODES


def to_degE7(north: float, east: float) -> tuple[int, int]:
    """Metres from home to integer degrees * 1e7."""
    return (round((HOME_LAT_DEG + north / M_PER_DEG_LAT) * 1e7),
            round((HOME_LON_DEG + east / M_PER_DEG_LON) * 1e7))


def vehicle_state(story: Story, t: float) -> VehicleState:
    """Position by linear interpolation between keyframes; flags from the story's events."""
    kfs = story.keyframes
    a, b = kfs[0], kfs[-1]
    for k0, k1 in zip(kfs, kfs[1:]):
        if k0.t <= t < k1.t:
            a, b = k0, k1
            break
    else:
        a = b = kfs[0] if t < kfs[0].t else kfs[-1]
    span = b.t - a.t
    f = (t - a.t) / span if span > 0 else 0.0
    north, east = a.north + (b.north - a.north) * f, a.east + (b.east - a.east) * f
    alt = a.alt + (b.alt - a.alt) * f
    vn, ve, vu = ((b.north - a.north) / span, (b.east - a.east) / span, (b.alt - a.alt) / span) \
        if span > 0 else (0.0, 0.0, 0.0)
    lat, lon = to_degE7(north, east)
    armed = story.arm_at is not None and story.arm_at + 0.05 <= t \
        and not (story.landed_at is not None and t >= story.landed_at)
    mode = "HOLD"
    if armed:
        mode = "MISSION"
    if story.reposition_at is not None and t >= story.reposition_at + 0.05:
        mode = "HOLD"
    if story.rtl_at is not None and t >= story.rtl_at + 0.05:
        mode = "RTL"
    return VehicleState(lat, lon, alt, vn, ve, -vu, a.heading + (b.heading - a.heading) * f, armed, mode)




PX4_UDP_STORY = Story(
    duration=60.0,
    keyframes=(Keyframe(0, 0, 0, 0, 90), Keyframe(17, 0, 0, 0, 90), Keyframe(22, 0, 0, 20, 45),
               Keyframe(30, 60, 60, 20, 45), Keyframe(31, 60, 60, 20, 45), Keyframe(35, 110, 10, 20, 315),
               Keyframe(36, 110, 10, 20, 315), Keyframe(40, 90, -40, 25, 250), Keyframe(44, 90, -40, 25, 250),
               Keyframe(53, 0, 0, 25, 180), Keyframe(58, 0, 0, 0, 180), Keyframe(60, 0, 0, 0, 180)),
    mission_at=5.0, arm_at=15.0, reposition_at=36.0, rtl_at=44.0, landed_at=58.5,
    statustexts=((15.2, MAV_SEVERITY_INFO, "Armed by external command"),
                 (17.3, MAV_SEVERITY_INFO, "Takeoff detected"),
                 (44.1, MAV_SEVERITY_INFO, "RTL: start return at 513 m (25 m above home)"),
                 (58.4, MAV_SEVERITY_INFO, "Landing detected"),
                 (58.6, MAV_SEVERITY_WARNING, "Disarmed by landing")),
    waypoints=((60.0, 60.0, 20.0), (110.0, 10.0, 20.0)),
    reposition_to=(90.0, -40.0, 25.0),
)

SHORT_STORY = Story(  # ~20 s: mission upload, arm, short hop, RTL
    duration=20.0,
    keyframes=(Keyframe(0, 0, 0, 0, 90), Keyframe(8, 0, 0, 0, 90), Keyframe(10, 0, 0, 10, 45),
               Keyframe(14, 20, 20, 10, 45), Keyframe(19, 0, 0, 10, 225), Keyframe(20, 0, 0, 8, 225)),
    mission_at=2.0, arm_at=7.0, rtl_at=14.0,
    statustexts=((7.2, MAV_SEVERITY_INFO, "Armed by external command"),
                 (14.1, MAV_SEVERITY_INFO, "RTL: start return")),
    waypoints=((20.0, 20.0, 10.0), (30.0, -10.0, 10.0)),
)
