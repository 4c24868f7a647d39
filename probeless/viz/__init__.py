"""Viewers: probeless messages as Rerun archetypes (live sink, .rrd export) and Foxglove channels."""
