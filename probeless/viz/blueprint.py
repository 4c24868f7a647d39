"""The default Rerun layout of a probeless run (entity tree: :mod:`probeless.viz.rerun_logger`).

Every view names the entities of the main pipeline (launch/probeless.yaml); a view whose entities a graph
does not publish stays empty, which Rerun shows as an empty panel (other graphs still get the 3D scene
and the time series of their own topics).
"""

from __future__ import annotations

import numpy as np
import rerun.blueprint as rrb

CAMERA = "/world/camera/rgbd/image"
FISHEYE = ("/undistort/image", "/interp/fisheye", "/rig/fisheye")
ATLAS = ("/texturer/atlas", "/texturer/observed", "/texturer/occlusion")
ENVMAPS = "/envmap/envmaps"


def room_eye(vertices: np.ndarray, ceiling_height: float) -> rrb.EyeControls3D:
    """A 3D eye above and in front of a floorplan's room, looking at its middle (a dollhouse view)."""
    lo, hi = np.min(vertices, axis=0), np.max(vertices, axis=0)
    (cx, cy), extent = (lo + hi) / 2, float(np.max(hi - lo))
    return rrb.EyeControls3D(position=[cx - 0.25 * extent, cy - 1.1 * extent, ceiling_height + 0.9 * extent],
                             look_target=[cx, cy, 0.3 * ceiling_height], eye_up=[0.0, 0.0, 1.0])


def default_blueprint(eye: rrb.EyeControls3D | None = None) -> rrb.Blueprint:
    """3D world | camera, fisheye, atlas, cubemap nets, timings, composited frame. ``eye``: the 3D view's
    camera (:func:`room_eye` once the floorplan is known; Rerun's default otherwise)."""
    scene = rrb.Spatial3DView(origin="/world", name="3D scene", eye_controls=eye)
    camera = rrb.Spatial2DView(origin=CAMERA, name="RGB-D camera")
    fisheye = rrb.Tabs(*(rrb.Spatial2DView(origin=p, name=p.strip("/")) for p in FISHEYE), name="fisheye")
    atlas = rrb.Tabs(*(rrb.Spatial2DView(origin=p, name=p.strip("/")) for p in ATLAS), name="atlas")
    nets = rrb.Spatial2DView(origin=ENVMAPS, name="cubemap nets")
    augmented = rrb.Spatial2DView(origin="/compositor/image", name="augmented frame")
    timings = rrb.TimeSeriesView(origin="/timings", name="timings [ms]")
    images = rrb.Grid(camera, augmented, fisheye, atlas, nets, timings)
    return rrb.Blueprint(rrb.Horizontal(scene, images, column_shares=[1, 1]), collapse_panels=False)
