"""Output nodes: write images to an MP4 video or to PNG files."""
