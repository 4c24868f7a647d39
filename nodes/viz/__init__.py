"""Live viewer nodes: ``rerun_sink`` (Rerun) and ``foxglove_bridge`` (Foxglove WebSocket)."""
