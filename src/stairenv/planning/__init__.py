"""PlaMo planning: instructions -> segments -> grid paths -> refined, timed waypoints."""
