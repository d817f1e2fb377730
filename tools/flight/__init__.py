"""Flight and link: latency from a decision to the vehicle, flights against SITL and the bundled simulator, a
second station on the link, tlog replays (``python -m tools`` lists the commands)."""
