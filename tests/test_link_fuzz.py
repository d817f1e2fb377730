"""Hostile input for the state tracker: every message type with extreme field values, and random bytes.

Nothing may raise, and nothing non-finite may reach the state.
"""

from __future__ import annotations

import math
import random

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.link.state import VehicleStateTracker

FLOATS = (math.nan, math.inf, -math.inf, 1e38, -1e38, 0.0)
NUMERIC_FIELDS = ("north_m", "east_m", "down_m", "north_m_s", "east_m_s", "down_m_s", "heading_deg",
                  "home_north_m", "home_east_m", "home_down_m", "home_alt_amsl_m", "alt_amsl_m", "relative_alt_m")


def _value(kind: str, length: int, rng: random.Random):
    base = kind.split("[")[0]
    if base == "char":
        return bytes(rng.randrange(256) for _ in range(max(length, 1)))
    if base in ("float", "double"):
        one = lambda: rng.choice(FLOATS + (rng.uniform(-1e6, 1e6),))  # noqa: E731
    else:
        bits = int("".join(c for c in base if c.isdigit()) or 8)
        signed = base.startswith("int")
        lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
        one = lambda: rng.choice((lo, hi, 0, rng.randint(lo, hi)))  # noqa: E731
    return [one() for _ in range(length)] if length > 1 else one()


def _random_message(cls, rng: random.Random):
    args = [_value(kind, length, rng) for kind, length in zip(cls.fieldtypes, cls.array_lengths)]
    # pymavlink lists fields in declaration order for the constructor
    ordered = [args[cls.ordered_fieldnames.index(name)] if name in cls.ordered_fieldnames else 0
               for name in cls.fieldnames]
    return cls(*ordered)


def _tracker_with_vehicle() -> VehicleStateTracker:
    tracker = VehicleStateTracker()
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    beat = mav.heartbeat_encode(2, 3, 217, 4, 4)
    beat.pack(mav)
    tracker.update(mavlink.MAVLink(None).parse_char(beat.get_msgbuf()), 0.0)
    return tracker


def test_every_message_type_with_extreme_values() -> None:
    rng = random.Random(1234)
    tracker = _tracker_with_vehicle()
    mapper = ActionMapper()
    sender = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    sender.robust_parsing = True
    built = 0
    for cls in mavlink.mavlink_map.values():
        for _ in range(3):
            try:
                msg = _random_message(cls, rng)
                packed = msg.pack(sender)
            except Exception:  # pymavlink itself refuses some values (e.g. out-of-range struct packing)
                continue
            parser = mavlink.MAVLink(None)
            parser.robust_parsing = True
            try:
                decoded = parser.parse_char(packed)
            except Exception:
                continue
            if decoded is None:
                continue
            built += 1
            tracker.update(decoded, float(built))
            state = tracker.snapshot(float(built))
            for name in NUMERIC_FIELDS:
                value = getattr(state, name)
                assert value is None or math.isfinite(value), (cls.__name__, name, value)
            mapper.apply(rng.choice(("go_forward", "up", "down", "turn_left", "stop")), state)
            sp = mapper.setpoint(state)
            assert all(math.isfinite(v) for v in (sp.forward_m_s, sp.right_m_s, sp.down_m_s, sp.yaw_deg))
    assert built > 300  # most of the dialect was exercised
    assert tracker.state.system_id == 1


def test_random_bytes_never_raise() -> None:
    rng = random.Random(99)
    tracker = _tracker_with_vehicle()
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    messages = 0
    for _ in range(200):
        blob = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300)))
        if rng.random() < 0.5:
            blob = b"\xfd" + blob  # look like MAVLink 2 often
        try:
            got = parser.parse_buffer(blob) or []
        except Exception:
            got = []
        for msg in got:
            messages += 1
            tracker.update(msg, 1.0)
    assert tracker.state.system_id == 1
