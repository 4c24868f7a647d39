"""``probeless eval envmap --oracle``: environment maps at the virtual objects against the rig's ground truth.

The oracle mode: an offline re-implementation of the graph given the true fisheye poses, extrinsics and camera
model and the exact floorplan (no SLAM, Δ corrected before fusion), an upper bound on what the graph can do.
One pass renders the scene's frames once (fisheye frames with their true poses, RGB-D frames for
the dense model); then every method runs over the same frames in stamp order, as the graph's nodes
would: Δ of frame k against the atlas after k-1, texture update, and every ``every`` fisheye
frames a cubemap per object, compared with the true cubemap there (through the fisheye's exposure,
so in the same camera LDR units). Methods (paper §5.3): ``ours``; ``baseline`` (the fisheye
rotated into the map, translation ignored, never cleared) and ``baseline_dense`` (plus the dense
model on top); ablations ``no_inpainting``, ``no_brightness``, ``no_dense``, ``no_occlusion``.

Scores: :func:`probeless.envmap.score.score_envmap` (the truth in LDR through the fisheye's exposure, and the
linear HDR truth), every method over the same *common* texels, those both ``ours`` and ``baseline`` observed
(:meth:`EnvmapRenderer.observed_mask`, :meth:`BaselineMap.observed`; a method's own observed texels when either
is not run), plus the earlier whole-map scores (:data:`probeless.envmap.methods.METRICS`). Maps are kept until
every method has run, then scored.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from probeless.coarse.brightness import apply_deadband, draw_sample, estimate_delta
from probeless.coarse.frames import FOV_MARGIN_DEG, runtime_model
from probeless.coarse.model import CoarseConfig, CoarseModel
from probeless.color import srgb_to_linear
from probeless.envmap import metrics as M
from probeless.envmap.baseline import BaselineMap
from probeless.envmap.cubemap import SPLAT_COVER, EnvmapRenderer
from probeless.envmap.dense_points import DensePoints
from probeless.envmap.methods import METHODS, METRICS, VARIANT
from probeless.envmap.score import score_envmap
from probeless.envmap.sh import project_cubemap
from probeless.progress import progress

MODE = "oracle"


@dataclass
class Rendered:
    """The scene's frames, rendered once for every method."""

    scene: object
    rig: object
    model: object                       # runtime fisheye model
    events: list                        # (kind, t, stamp_ns, payload) in time order
    eval_times: list[float]             # fisheye times at which maps are compared
    truth: dict[tuple[str, float], np.ndarray] = field(default_factory=dict)  # (object, t) -> LDR faces 0..1
    truth_hdr: dict[tuple[str, float], np.ndarray] = field(default_factory=dict)  # (object, t) -> radiance
    exposure: dict[float, np.ndarray] = field(default_factory=dict)  # t -> the fisheye's (3,) linear gains


def render_frames(scene_path, duration: float | None, *, stride: int, rgbd_stride: int, every: int,
                  face_size: int, show_progress: bool) -> Rendered:
    """Render fisheye and RGB-D frames, the true maps at the evaluation times, and the dense snapshots."""
    from probeless.cameras.undistort import remap
    from probeless.scene.parse import load_scene
    from probeless.scene.rig import Rig, frame_schedule

    scene = load_scene(scene_path)
    rig = Rig(scene, envmaps=False, envmap_size=face_size)
    model, lut = runtime_model(rig.fisheye, scene.fisheye.fov_deg)
    schedule = frame_schedule(scene, duration)
    fish = [e for e in schedule if e.kind == "fisheye"][::max(1, stride)]
    rgbd = [e for e in schedule if e.kind == "rgbd"][::max(1, rgbd_stride)]
    chosen = sorted(fish + rgbd, key=lambda e: (e.t, e.kind != "rgbd"))
    eval_times = [e.t for k, e in enumerate(fish) if k % every == 0 or k == len(fish) - 1]
    objects = scene.virtual_objects
    out = Rendered(scene, rig, model, [], eval_times)
    with progress(len(chosen), f"render {scene.name}", enabled=show_progress) as tick:
        for e in chosen:
            if e.kind == "rgbd":
                rgb, depth, pose = rig.render_rgbd(e)
                out.events.append(("rgbd", e.t, e.stamp_ns, (rgb, depth.astype(np.float32) / 1000.0, pose)))
            else:
                image, pose = rig.render_fisheye(e)
                out.events.append(("fisheye", e.t, e.stamp_ns, (image if lut is None else remap(image, lut), pose,
                                                                 rig.light_scale(e.t))))
                if e.t in eval_times:
                    out.exposure[e.t] = np.asarray(rig.fisheye_gains(), np.float64)
                    for o in objects:
                        radiance = rig.render_envmap(o.position, e.t)
                        out.truth_hdr[o.id, e.t] = radiance.astype(np.float32)
                        out.truth[o.id, e.t] = rig.fisheye_ldr(radiance).astype(np.float32) / 255.0
            tick()
    return out


@dataclass
class MethodResult:
    """Per object: metric -> series over the evaluation times; the maps until they are scored."""

    method: str
    series: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    last_faces: dict[str, np.ndarray] = field(default_factory=dict)
    maps: dict[tuple[str, float], tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)  # -> (est, observed)

    def keep(self, obj: str, t: float, est: np.ndarray, observed: np.ndarray) -> None:
        """Hold one map and its observed mask (6, S, S) for :func:`score_results`."""
        self.maps[obj, t] = (est, observed)
        self.last_faces[obj] = est

    def add(self, obj: str, values: dict[str, float]) -> None:
        per = self.series.setdefault(obj, {k: [] for k in METRICS})
        for k, v in values.items():
            per[k].append(float(v))

    def means(self) -> dict[str, dict[str, float]]:
        return {o: {k: float(np.nanmean(v)) if v else float("nan") for k, v in per.items()}
                for o, per in self.series.items()}


def score(est: np.ndarray, truth: np.ndarray, observed: np.ndarray, *, truth_hdr: np.ndarray | None = None,
          exposure=1.0, common: np.ndarray | None = None) -> dict[str, float]:
    """The metrics of one estimated LDR cubemap against the true one (module doc): the whole-map scores and,
    given ``truth_hdr``, :func:`~probeless.envmap.score.score_envmap`'s."""
    out = {"envmap_psnr": M.envmap_psnr(est, truth), "envmap_ssim": M.envmap_ssim(est, truth),
           "coverage": M.coverage(observed), "mirror_psnr": M.mirror_psnr(est, truth),
           "diffuse_psnr": M.diffuse_psnr(est, truth),
           "sh_rel_error": M.sh_rel_error(project_cubemap(srgb_to_linear(np.clip(est, 0, 1))),
                                          project_cubemap(srgb_to_linear(np.clip(truth, 0, 1))))}
    if truth_hdr is not None:
        out.update(score_envmap(est, truth, truth_hdr, exposure=exposure, observed=observed, common=common))
    return out


def score_results(r: Rendered, results: dict[str, MethodResult]) -> None:
    """Score every kept map over the texels both ``ours`` and ``baseline`` observed (module doc), then drop them."""
    for t in r.eval_times:
        for o in r.scene.virtual_objects:
            pair = [results[m].maps[o.id, t][1] for m in ("ours", "baseline") if m in results]
            common = pair[0] & pair[1] if len(pair) == 2 else None
            for res in results.values():
                est, observed = res.maps[o.id, t]
                res.add(o.id, score(est, r.truth[o.id, t], observed, truth_hdr=r.truth_hdr[o.id, t],
                                    exposure=r.exposure[t], common=observed if common is None else common))
    for res in results.values():
        res.maps.clear()


def _coarse_config(variant: str, atlas_size: int, fov_deg: float) -> tuple[CoarseConfig, bool]:
    config = CoarseConfig(atlas_size=atlas_size, fov_deg=fov_deg, inpaint=variant != "no_inpainting",
                          occlusion=variant != "no_occlusion")
    return config, variant != "no_brightness"


@dataclass
class Replay:
    """The models one replay of the frames drives (:func:`make_replay`, :func:`replay`): the coarse model
    (None for the baseline) or the baseline map, the dense points and the summed Δ."""

    coarse: CoarseModel | None
    base: BaselineMap | None
    dense: DensePoints
    delta_sum: np.ndarray
    fov: float
    use_delta: bool = False
    sample: np.ndarray | None = None

    def release(self) -> None:
        """Free the coarse model's GL objects."""
        if self.coarse is not None:
            self.coarse.release()


def make_replay(r: Rendered, variant: str | None, *, atlas_size: int, face_size: int) -> Replay:
    """Fresh models for one run of ``variant`` (a coarse-model variant, or None: the baseline map)."""
    scene, ctx = r.scene, r.rig.renderer.ctx
    fov = scene.fisheye.fov_deg - FOV_MARGIN_DEG
    dense = DensePoints(np.array([o.position for o in scene.virtual_objects]))
    if variant is None:
        return Replay(None, BaselineMap(face_size, r.model, fov), dense, np.zeros(3), fov)
    config, use_delta = _coarse_config(variant, atlas_size, fov)
    coarse = CoarseModel(scene.floorplan, scene.ceiling_height, config, ctx=ctx)
    return Replay(coarse, None, dense, np.zeros(3), fov, use_delta, draw_sample(coarse.texmap, 65536, seed=0))


def replay(r: Rendered, state: Replay, *, on_eval=None, show_progress: bool = True, label: str = "") -> Replay:
    """Drive ``state``'s models over the frames in stamp order, as the graph's nodes would (module doc);
    ``on_eval(t, state)`` at each evaluation time. Returns ``state``."""
    scene, K = r.scene, r.scene.rgbd.K
    with progress(len(r.events), label, enabled=show_progress) as tick:
        for kind, t, _, payload in r.events:
            tick()
            if kind == "rgbd":
                rgb, depth, pose = payload
                state.dense.add(rgb.astype(np.float64) - state.delta_sum * 255.0, depth, K, pose)
                continue
            image, pose, _ = payload
            if state.coarse is None:
                state.base.update(image, pose)
            else:
                coarse = state.coarse
                delta = np.zeros(3, np.float32)
                if state.use_delta and coarse.frames > 0:
                    packed = coarse.gpu.read_packed()
                    delta, _ = estimate_delta(packed[..., :3], packed[..., 3] > 0, coarse.texmap, image, r.model,
                                              pose, state.fov, scene.floorplan, sample_idx=state.sample)
                    delta = apply_deadband(delta)
                coarse.step(image, r.model, pose, delta, t)
                state.delta_sum += delta
            if t in r.eval_times and on_eval is not None:
                on_eval(t, state)
    return state


def run_variant(r: Rendered, variant: str, methods: list[str], *, atlas_size: int, face_size: int,
                results: dict[str, MethodResult], show_progress: bool) -> None:
    """One coarse-model run (or the baseline when ``variant`` is None) scoring every method that uses it."""
    state = make_replay(r, variant, atlas_size=atlas_size, face_size=face_size)
    layout = _dummy_layout(r.scene) if state.coarse is None else state.coarse.layout
    renderer = EnvmapRenderer(layout, ctx=r.rig.renderer.ctx)

    def on_eval(t: float, st: Replay) -> None:
        _keep_step(r, t, st.coarse, st.base, renderer, st.dense, st.delta_sum, methods, face_size, results)

    replay(r, state, on_eval=on_eval, show_progress=show_progress, label=f"{variant or 'baseline'}")
    renderer.release()
    state.release()


def _dummy_layout(scene):
    from probeless.coarse.atlas import layout_atlas

    return layout_atlas(scene.floorplan, scene.ceiling_height, 4.0)


def _keep_step(r, t, coarse, base, renderer, dense, delta_sum, methods, size, results) -> None:
    """Render (or copy) every method's map at time ``t`` for each object and keep it with its observed mask."""
    points, colours = dense.points()
    splat = {"splat_m": SPLAT_COVER * dense.voxel_m}
    if len(points):
        renderer.set_dense(points, colours, normals=dense.normals())
    else:
        renderer.clear_dense()
    if coarse is None:  # the baseline's renderer draws the dense model alone, over an unobserved black atlas
        renderer.set_atlas(np.zeros((renderer.layout.height, renderer.layout.width, 4), np.uint8))
    else:
        renderer.set_atlas(coarse.gpu.read_packed())
    for o in r.scene.virtual_objects:
        pos = np.asarray(o.position, np.float64)
        if coarse is not None:
            for m in methods:
                with_dense = m != "no_dense" and len(points) > 0
                est = renderer.render(pos, size, delta=delta_sum, dense=with_dense, **splat)
                results[m].keep(o.id, t, est, renderer.observed_mask(pos, size, dense=with_dense, **splat))
            continue
        for m in methods:
            est, observed = base.faces.copy(), base.observed()
            if m == "baseline_dense" and len(points):
                covered = renderer.observed_mask(pos, size, **splat)
                est = np.where(covered[..., None], renderer.render(pos, size, delta=delta_sum, **splat), est)
                observed |= covered
            results[m].keep(o.id, t, est, observed)


def evaluate_envmaps(scene_path, *, duration: float | None = None, methods=METHODS, face_size: int = 64,
                     atlas_size: int = 512, every: int = 3, stride: int = 1, rgbd_stride: int = 3,
                     show_progress: bool = True) -> tuple[Rendered, dict[str, MethodResult]]:
    """Score every method in ``methods`` on a scene (module doc)."""
    unknown = set(methods) - set(METHODS)
    if unknown:
        from probeless.errors import ProbelessError

        raise ProbelessError(f"unknown method(s) {sorted(unknown)}; choose from {', '.join(METHODS)}")
    r = render_frames(scene_path, duration, stride=stride, rgbd_stride=rgbd_stride, every=every,
                      face_size=face_size, show_progress=show_progress)
    results = {m: MethodResult(m) for m in methods}
    variants: dict[str | None, list[str]] = {}
    for m in methods:
        variants.setdefault(VARIANT[m], []).append(m)
    for variant, ms in variants.items():
        run_variant(r, variant, ms, atlas_size=atlas_size, face_size=face_size, results=results,
                    show_progress=show_progress)
    score_results(r, results)
    return r, results
