"""Camera tracking: dense SLAM poses, pose interpolation in time and their evaluation."""
