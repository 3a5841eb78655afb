"""The `ros2` interface: message definitions, generated message types, wire details."""
