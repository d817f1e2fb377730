"""The simulator's composition root: room, physics, vehicle, personality, links and tlog as one SimServer.

``gcs-sim``, the tests and the benchmarks all build a simulator here, so they fly the same thing.
"""

from __future__ import annotations

import math

from collections.abc import Sequence
from pathlib import Path

from sim_bridge.access import PeerFilter
from sim_bridge.fdm import GEAR_HEIGHT_M
from sim_bridge.frames import room_to_ned
from sim_bridge.mavlink_server import SimServer
from sim_bridge.multicopter import Multicopter
from sim_bridge.params import load_params
from sim_bridge.transport import TcpServer, TlogWriter, TransportError, UdpOutLink, parse_endpoint
from sim_bridge.vehicle import Vehicle
from sim_bridge.world import load_contact_params, load_room

__all__ = ["AUTOPILOTS", "SimUsageError", "build_sim"]

AUTOPILOTS = ("ardupilot", "px4")


class SimUsageError(ValueError):
    """A flag value gcs-sim cannot use; printed as one line."""


def build_sim(autopilot: str = "ardupilot", room: str = "living_room", home: tuple[float, float, float] | None = None,
              outs: Sequence[str] = (), tcp: Sequence[str] = (), tlog: Path | None = None,
              epoch_unix_s: float | None = None, signing_key: bytes | None = None,
              allow: Sequence[str] = (), cold_start_scale: float | None = None) -> SimServer:
    """A ready SimServer (nothing runs until ``step``/``run_for``/``serve``). ``signing_key``: 32 bytes
    (``sim_bridge.signing.key_from_flag``); ``allow``: ``--allow`` values (``sim_bridge.access``);
    ``cold_start_scale``: boot like the real autopilot (``autopilot.boot``), its times multiplied by this.
    """
    if cold_start_scale is not None and not (math.isfinite(cold_start_scale) and cold_start_scale > 0):
        raise SimUsageError(f"--boot-scale {cold_start_scale!r}: a positive number")
    if autopilot not in AUTOPILOTS:
        raise SimUsageError(f"--autopilot {autopilot!r}: one of {', '.join(AUTOPILOTS)}")
    links, servers = [], []
    peer_filter = PeerFilter(allow) if allow else None
    try:
        for out in outs:
            scheme, _, rest = out.partition(":")
            if scheme != "udp" or not rest:
                raise SimUsageError(f"--out {out!r}: expected udp:HOST:PORT")
            links.append(UdpOutLink(*parse_endpoint(rest)))
            links[-1].peer_filter = peer_filter
        for spec in tcp:
            servers.append(TcpServer(*parse_endpoint(spec)))
            servers[-1].peer_filter = peer_filter
    except (TransportError, SimUsageError):
        for item in [*links, *servers]:
            item.close()
        raise
    room_obj = load_room(room)
    kwargs = {} if home is None else {"home_lat_deg": home[0], "home_lon_deg": home[1], "home_alt_m": home[2]}
    multicopter = Multicopter(room_obj, **kwargs)
    vehicle = Vehicle(multicopter)
    if room_obj.walls:
        # Where the gear point may go: walls and ceiling less the vehicle's contact sphere (and its CG height).
        radius_m = load_contact_params().vehicle_radius_m
        lo = room_to_ned(room_obj.bounds_min_m, room_obj.start_xy_m)
        hi = room_to_ned(room_obj.bounds_max_m, room_obj.start_xy_m)
        vehicle.room_box_ned_m = (min(lo[0], hi[0]) + radius_m, max(lo[0], hi[0]) - radius_m,
                                  min(lo[1], hi[1]) + radius_m, max(lo[1], hi[1]) - radius_m)
        vehicle.ceiling_m = room_obj.bounds_max_m[2] - room_obj.bounds_min_m[2] - GEAR_HEIGHT_M - radius_m
    params = load_params(autopilot)
    home_fix = (multicopter.home_lat_deg, multicopter.home_lon_deg, multicopter.home_alt_m)
    server = SimServer(vehicle, autopilot, params, home_fix, tlog=TlogWriter(tlog) if tlog else None,
                       epoch_unix_s=epoch_unix_s)
    if signing_key is not None:
        server.signing.set_key(signing_key, 0)
    server.peer_filter = peer_filter
    if cold_start_scale is not None:
        server.autopilot.start_cold(cold_start_scale)
    for link in links:
        server.add_link(link)
    for tcp_server in servers:
        server.add_tcp_server(tcp_server)
    return server
