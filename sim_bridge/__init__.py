"""sim_bridge: a bundled quadrotor simulator (JSBSim dynamics) that speaks MAVLink like ArduCopter or PX4.

Layers: ``fdm`` (JSBSim) <- ``control`` (velocity -> attitude -> rate -> motors) <- ``vehicle``
(modes, commands, timeouts) <- ``mavlink_server`` (the wire); ``world`` holds rooms and contacts.
The voice bridge never imports this package: they meet only over MAVLink, as a real drone would.
"""

__version__ = "0.1.0"
