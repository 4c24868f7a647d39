"""Tracking nodes: dense SLAM and the fisheye pose from interpolated RGB-D poses."""
