"""`hfsmc sim`: a simulated multicopter (MAVLink over UDP, like ArduPilot Copter in
GUIDED mode) and its downward camera (MJPEG over HTTP), over a world (docs/worlds.md)."""
