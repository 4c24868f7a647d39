"""``probeless coarse preview``: pictures of the coarse model filling in as the camera moves.

Writes, into the output folder: ``model_overview.png`` and ``model_inside.png`` (the textured
prism from two viewpoints with the RGB-D camera (green) and fisheye (orange) frusta and the
fisheye's path, like the paper's Figures 4 and 8), ``atlas.png``, ``observed.png`` (white
observed, grey inpainted), ``occlusion.png`` (one frame's atlas-space occlusion mask: white
visible, red occluded by the room), ``visibility.png`` (that frame's 2-D visibility polygon),
``filling.png`` (the atlas at several times) and ``sheet.png`` (all of them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from probeless.coarse.frames import open_source
from probeless.coarse.model import CoarseConfig
from probeless.coarse.run import run_coarse
from probeless.coarse.view import (
    GREEN,
    ORANGE,
    WHITE,
    ModelView,
    fisheye_lines,
    frustum_lines,
    inside_camera,
    overview_camera,
    polyline,
)
from probeless.coarse.visibility import visibility_polygon
from probeless.scene.preview import contact_sheet, write_png

VIEW_K = np.array([[560.0, 0, 479.5], [0, 560.0, 359.5], [0, 0, 1]])
VIEW_SIZE = (960, 720)


@dataclass
class Capture:
    """What the preview keeps while the run goes."""

    snapshot_frames: set[int]
    occlusion_frame: int
    snapshots: list[tuple[float, np.ndarray, float]] = field(default_factory=list)  # (t, atlas rgb, coverage)
    occlusion: np.ndarray | None = None
    occlusion_pose: np.ndarray | None = None
    path: list[np.ndarray] = field(default_factory=list)
    last_pose: np.ndarray | None = None

    def __call__(self, model, frame, rec) -> None:
        k = model.frames - 1
        self.path.append(frame.world_from_fisheye[:3, 3].copy())
        self.last_pose = frame.world_from_fisheye
        if k == self.occlusion_frame:
            self.occlusion, self.occlusion_pose = model.gpu.read_occlusion(), frame.world_from_fisheye
        if k in self.snapshot_frames:
            packed = model.gpu.read_packed()
            core = model.texmap.core
            self.snapshots.append((frame.t_s, packed[..., :3].copy(), float((packed[..., 3] > 0)[core].mean())))


def occlusion_picture(mask: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """White = visible, red = occluded by the room, black = no surface."""
    out = np.zeros(mask.shape + (3,), np.uint8)
    out[valid & mask] = 255
    out[valid & ~mask] = (200, 40, 40)
    return out


def visibility_picture(floorplan: np.ndarray, viewpoint: np.ndarray, size: int = 600) -> np.ndarray:
    """Top view: the floorplan (grey), the visibility polygon (light) and the viewpoint (orange)."""
    lo, hi = floorplan.min(axis=0), floorplan.max(axis=0)
    scale = (size - 40) / float(np.max(hi - lo))
    to_px = lambda p: np.round((np.c_[p[:, 0] - lo[0], hi[1] - p[:, 1]]) * scale + 20).astype(np.int32)  # noqa: E731
    img = np.full((size, size, 3), 24, np.uint8)
    cv2.fillPoly(img, [to_px(floorplan)], (90, 90, 90))
    cv2.fillPoly(img, [to_px(visibility_polygon(floorplan, viewpoint))], (230, 225, 200))
    cv2.polylines(img, [to_px(floorplan)], True, (255, 255, 255), 2)
    cv2.circle(img, tuple(int(v) for v in to_px(np.asarray(viewpoint)[None])[0]), 6, (255, 140, 25), -1)
    return img


def filling_strip(snapshots: list[tuple[float, np.ndarray, float]], tile: int = 360) -> np.ndarray:
    """The atlas at each snapshot side by side, labelled with time and observed coverage."""
    tiles = []
    for t, rgb, coverage in snapshots:
        img = cv2.resize(rgb, (tile, tile), interpolation=cv2.INTER_AREA)
        cv2.putText(img, f"t={t:.1f}s  seen {100 * coverage:.0f}%", (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55,
                    (255, 255, 0), 1, cv2.LINE_AA)
        tiles.append(img)
    return np.hstack(tiles)


def preview(source_path: str | Path, out_dir: str | Path, *, duration: float | None = None,
            atlas_size: int = 1024, snapshots: int = 4, show_progress: bool = True) -> list[Path]:
    """Run the coarse model over a scene or recording and write the preview pictures; their paths."""
    source = open_source(source_path, duration)
    n = max(1, source.count)
    cap = Capture(set(np.linspace(0, n - 1, max(1, snapshots)).round().astype(int).tolist()), n // 2)
    config = CoarseConfig(atlas_size=atlas_size, fov_deg=source.texture_fov_deg)
    model, _ = run_coarse(source, config, on_frame=cap, show_progress=show_progress)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rgb = model.gpu.read_packed()[..., :3].copy()
    pictures = {"atlas": rgb, "observed": cv2.cvtColor(model.observed_image(), cv2.COLOR_GRAY2RGB)}
    if cap.occlusion is not None:
        pictures["occlusion"] = occlusion_picture(cap.occlusion, model.texmap.valid)
        pictures["visibility"] = visibility_picture(source.floorplan, cap.occlusion_pose[:2, 3])
    pictures["filling"] = filling_strip(cap.snapshots)
    view = ModelView(model.layout, ctx=model.gpu.ctx)
    lines = [(polyline(np.array(cap.path)), WHITE), (fisheye_lines(cap.last_pose, source.fov_deg, 0.35), ORANGE)]
    if source.rig is not None:
        scene = source.rig.scene
        rgbd = cap.last_pose @ scene.fisheye_from_rgbd
        lines.append((frustum_lines(rgbd, scene.rgbd.K, (scene.rgbd.width, scene.rgbd.height), 0.45), GREEN))
    pictures["model_overview"] = view.render(rgb, overview_camera(model.layout), VIEW_K, VIEW_SIZE, lines,
                                             ceiling=False)
    pictures["model_inside"] = view.render(rgb, inside_camera(model.layout), VIEW_K, VIEW_SIZE, lines)
    model.release()
    written = []
    for name, img in pictures.items():
        written.append(out / f"{name}.png")
        write_png(written[-1], img)
    order = ["model_overview", "model_inside", "atlas", "observed", "occlusion", "visibility"]
    sheet = contact_sheet([(k, pictures[k]) for k in order if k in pictures], columns=2)
    written.append(out / "sheet.png")
    write_png(written[-1], sheet)
    return written
