"""The parameter and mission micro-protocols, as small state machines the server feeds.

Parameters: PARAM_REQUEST_LIST streams every PARAM_VALUE (index, count) to the link that asked,
a few per tick as the firmware does; PARAM_REQUEST_READ answers one; PARAM_SET answers with the value
now held, to every link. Missions: gcs-sim has no AUTO mode, so the mission is what the firmware
holds when nothing was uploaded (ArduCopter: home as item 0 once home is set; PX4: nothing).
"""

from __future__ import annotations

from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.params import ParamStore

__all__ = ["ParamProtocol", "mission_reply"]

#: PARAM_VALUE messages sent per tick while a list download runs (1354 took 0.9 s on real SITL).
PARAMS_PER_TICK = 16


class ParamProtocol:
    def __init__(self, params: ParamStore, server: Any) -> None:
        self.params = params
        self.server = server
        self._queues: dict[int, tuple[Any, list[int]]] = {}   # id(link) -> (link, indices still to send)

    def _value_msg(self, index: int) -> Any:
        param = self.params.at(index)
        assert param is not None
        return self.server._tlog_mav.param_value_encode(param.name.encode(), self.params.encode(param), param.mav_type,
                                                        len(self.params), index)

    def handle(self, msg: Any, link: Any) -> None:
        kind = msg.get_type()
        if kind == "PARAM_REQUEST_LIST":
            self._queues[id(link)] = (link, list(range(len(self.params))))
            for line in self.server.autopilot.texts.get("params", []):
                self.server.text(mavlink.MAV_SEVERITY_INFO, line)
        elif kind == "PARAM_REQUEST_READ":
            index = msg.param_index if msg.param_index >= 0 else self.params.index_of(_name(msg.param_id))
            if self.params.at(index) is not None:
                self.server.send(self._value_msg(index), link)
        elif kind == "PARAM_SET":
            name = _name(msg.param_id)
            if name not in self.params:
                return      # both firmwares stay silent about unknown names
            self.params.set(name, self.params.decode(msg.param_value, msg.param_type, name))
            self.server.send(self._value_msg(self.params.index_of(name)))

    def trickle(self) -> None:
        """Send the next few PARAM_VALUE of every running list download."""
        for key, (link, pending) in list(self._queues.items()):
            if link.closed:
                del self._queues[key]
                continue
            for index in pending[:PARAMS_PER_TICK]:
                self.server.send(self._value_msg(index), link)
            del pending[:PARAMS_PER_TICK]
            if not pending:
                del self._queues[key]


def _name(param_id: Any) -> str:
    if isinstance(param_id, bytes):
        param_id = param_id.decode("ascii", "replace")
    return str(param_id).split("\0", 1)[0]


def mission_reply(msg: Any, items: list[tuple], mav: Any) -> Any:
    """The answer to one mission-protocol message, or None. ``items``: (frame, command, lat_e7, lon_e7, alt)."""
    kind = msg.get_type()
    src, comp = msg.get_srcSystem(), msg.get_srcComponent()
    mission_type = getattr(msg, "mission_type", mavlink.MAV_MISSION_TYPE_MISSION)
    own = items if mission_type == mavlink.MAV_MISSION_TYPE_MISSION else []
    if kind == "MISSION_REQUEST_LIST":
        return mav.mission_count_encode(src, comp, len(own), mission_type)
    if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
        if not 0 <= msg.seq < len(own):
            return mav.mission_ack_encode(src, comp, mavlink.MAV_MISSION_INVALID_SEQUENCE, mission_type)
        frame, command, lat_e7, lon_e7, alt = own[msg.seq]
        if kind == "MISSION_REQUEST_INT":
            return mav.mission_item_int_encode(src, comp, msg.seq, frame, command, 0, 1, 0, 0, 0, 0,
                                               lat_e7, lon_e7, alt, mission_type)
        return mav.mission_item_encode(src, comp, msg.seq, frame, command, 0, 1, 0, 0, 0, 0,
                                       lat_e7 / 1e7, lon_e7 / 1e7, alt, mission_type)
    if kind == "MISSION_CLEAR_ALL":
        return mav.mission_ack_encode(src, comp, mavlink.MAV_MISSION_ACCEPTED, mission_type)
    if kind == "MISSION_COUNT":
        result = mavlink.MAV_MISSION_ACCEPTED if msg.count == 0 else mavlink.MAV_MISSION_UNSUPPORTED
        return mav.mission_ack_encode(src, comp, result, mission_type)
    return None
