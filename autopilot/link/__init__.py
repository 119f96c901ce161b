"""The live MAVLink link to ground stations (issue 16): endpoints, telemetry, missions, commands, parameters."""
