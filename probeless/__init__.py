"""probeless: a ROS-style dataflow pipeline for probeless AR lighting."""

__version__ = "0.1.0"
