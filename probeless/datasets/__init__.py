"""Readers for RGB-D and fisheye datasets on disk (TUM, Redwood/Open3D, 7-Scenes, image folders, videos)."""
