"""A small valid scene file (as a dict) that scene, rig and SLAM tests edit."""

BASE = {
    "name": "t",
    "room": {"floorplan": [[0, 0], [4, 0], [4, 3], [0, 3]], "ceiling_height": 2.5,
             "windows": [{"wall": 0, "center": [2.0, 1.2], "size": [1.0, 0.8], "radiance": [5, 5, 5]}]},
    "lights": [{"position": [2.0, 1.5, 2.49], "size": [0.5, 0.5], "radiance": [20, 20, 20]}],
    "furniture": [{"box": {"center": [2.0, 1.5, 0.35], "size": [1.0, 0.6, 0.7]}, "color": [0.5, 0.4, 0.3]}],
    "virtual_objects": [{"id": "ball", "position": [2.0, 1.5, 0.9], "radius": 0.1}],
    "rig": {"rgbd": {"width": 64, "height": 48, "fx": 50, "fy": 50, "cx": 31.5, "cy": 23.5, "fps": 30},
            "fisheye": {"model": "omnidir", "width": 64, "height": 64, "fov_deg": 185, "fps": 15},
            "fisheye_from_rgbd": {"translation": [0, -0.06, -0.02], "rpy_deg": [-90, 0, 0]}},
    "trajectory": {"keyframes": [{"t": 0, "position": [0.8, 0.6, 1.4], "look_at": [2, 1.5, 0.8]},
                                 {"t": 2, "position": [3.2, 0.6, 1.4], "look_at": [2, 1.5, 0.8]}]},
}
