"""Action classes to setpoints: what "up" or "turn left" means for the vehicle (velocity, yaw, limits)."""
