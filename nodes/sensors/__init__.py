"""Sensor nodes: synthetic rig, dataset players, live camera drivers, fisheye undistortion."""
