"""Read the scene file's ``sensor_effects`` and ``given`` blocks (see probeless.scene.effects_spec)."""

from __future__ import annotations

from pathlib import Path

from probeless.scene.effects_spec import (
    AutoExposure,
    CameraEffects,
    ExtrinsicsError,
    Flicker,
    FloorplanError,
    Given,
    IntrinsicsError,
    KinectDepth,
    Noise,
    SensorEffects,
    Vignetting,
)
from probeless.scene.fields import Where, integer, mapping, number, string, vector

_CAMERA_KEYS = ("auto_exposure", "white_balance", "vignetting", "response", "noise", "exposure_time_s")


def parse_sensor_effects(v, where: Where) -> SensorEffects:
    """The ``sensor_effects`` mapping; every effect absent = off."""
    mapping(v, where, ("seed",), ("rgbd", "fisheye", "flicker", "depth"))
    flicker = depth = None
    if "flicker" in v:
        fw = where.child("flicker", v)
        f = mapping(v["flicker"], fw, ("amplitude",), ("frequency_hz", "phase_deg"))
        flicker = Flicker(number(f["amplitude"], fw.child("amplitude", f), min=0, max=1),
                          number(f.get("frequency_hz", 100.0), fw.child("frequency_hz", f), min=0, strict_min=True),
                          number(f.get("phase_deg", 0.0), fw.child("phase_deg", f)))
    if "depth" in v:
        depth = _depth(v["depth"], where.child("depth", v))
    cams = {k: _camera(v[k], where.child(k, v)) for k in ("rgbd", "fisheye") if k in v}
    return SensorEffects(integer(v["seed"], where.child("seed", v), min=0), flicker=flicker, depth=depth, **cams)


def _camera(v, where: Where) -> CameraEffects:
    mapping(v, where, (), _CAMERA_KEYS)
    out: dict = {}
    if "auto_exposure" in v:
        aw = where.child("auto_exposure", v)
        a = mapping(v["auto_exposure"], aw, ("target",), ("tau_s", "min", "max"))
        ae = AutoExposure(number(a["target"], aw.child("target", a), min=0, max=1, strict_min=True),
                          number(a.get("tau_s", 0.3), aw.child("tau_s", a), min=0),
                          number(a.get("min", 0.01), aw.child("min", a), min=0, strict_min=True),
                          number(a.get("max", 16.0), aw.child("max", a), min=0, strict_min=True))
        if ae.min > ae.max:
            raise aw.child("min", a).error(f"min {ae.min} is above max {ae.max}")
        out["auto_exposure"] = ae
    if "white_balance" in v:
        ww = where.child("white_balance", v)
        w = mapping(v["white_balance"], ww, ("gains",))
        out["wb_gains"] = tuple(vector(w["gains"], ww.child("gains", w), 3, min=0, strict_min=True).tolist())
    if "vignetting" in v:
        vw = where.child("vignetting", v)
        g = mapping(v["vignetting"], vw, ("model",), ("coeffs",))
        model = string(g["model"], vw.child("model", g), ("cos4", "poly"))
        coeffs = g.get("coeffs", [])
        if model == "poly" and not 1 <= len(coeffs or []) <= 3:
            raise vw.child("coeffs", g).error("poly vignetting needs 1 to 3 coefficients [k1, k2, k3]")
        if model == "cos4" and coeffs:
            raise vw.child("coeffs", g).error("cos4 vignetting takes no coefficients")
        out["vignetting"] = Vignetting(model, tuple(vector(coeffs, vw.child("coeffs", g), len(coeffs)).tolist()))
    if "response" in v:
        rw = where.child("response", v)
        r = mapping(v["response"], rw, ("model",), ("gamma",))
        if string(r["model"], rw.child("model", r), ("srgb", "gamma")) == "gamma":
            if "gamma" not in r:
                raise rw.error("missing key 'gamma'")
            out["gamma"] = number(r["gamma"], rw.child("gamma", r), min=0.2, max=5)
    if "noise" in v:
        nw = where.child("noise", v)
        n = mapping(v["noise"], nw, ("full_well",), ("read_sigma",))
        out["noise"] = Noise(number(n["full_well"], nw.child("full_well", n), min=1),
                             number(n.get("read_sigma", 0.0), nw.child("read_sigma", n), min=0, max=0.5))
    if "exposure_time_s" in v:
        out["exposure_time_s"] = number(v["exposure_time_s"], where.child("exposure_time_s", v),
                                        min=0, max=1, strict_min=True)
    return CameraEffects(**out)


def _depth(v, where: Where) -> KinectDepth:
    keys = ("sigma_k", "baseline_m", "focal_px", "disparity_step_px", "max_incidence_deg", "edge_jump_m",
            "edge_dropout", "flying_pixels")
    mapping(v, where, (), keys)
    limits = {"sigma_k": {"min": 0, "max": 0.1}, "baseline_m": {"min": 0, "strict_min": True},
              "focal_px": {"min": 0, "strict_min": True}, "disparity_step_px": {"min": 0, "max": 4},
              "max_incidence_deg": {"min": 1, "max": 90}, "edge_jump_m": {"min": 0, "strict_min": True},
              "edge_dropout": {"min": 0, "max": 1}, "flying_pixels": {"min": 0, "max": 1}}
    d = {k: number(v[k], where.child(k, v), **limits[k]) for k in keys if k in v}
    if d.get("edge_dropout", 0) + d.get("flying_pixels", 0) > 1:
        raise where.error("edge_dropout + flying_pixels must be <= 1 (both act on discontinuity pixels)")
    return KinectDepth(**d)


def parse_given(v, where: Where, root: Path) -> Given:
    """The ``given`` mapping; ``root`` resolves ``from_file`` paths."""
    mapping(v, where, ("seed",), ("floorplan", "extrinsics", "fisheye_intrinsics", "clock_offset_s"))
    out: dict = {}
    if "floorplan" in v:
        fw = where.child("floorplan", v)
        f = mapping(v["floorplan"], fw, (), ("vertex_sigma_m", "rotation_deg", "ceiling_m"))
        out["floorplan"] = FloorplanError(
            number(f.get("vertex_sigma_m", 0.0), fw.child("vertex_sigma_m", f), min=0, max=0.5),
            number(f.get("rotation_deg", 0.0), fw.child("rotation_deg", f), min=-45, max=45),
            number(f.get("ceiling_m", 0.0), fw.child("ceiling_m", f), min=-1, max=1))
    if "extrinsics" in v:
        ew = where.child("extrinsics", v)
        e = mapping(v["extrinsics"], ew, (), ("translation_sigma_m", "rotation_sigma_deg", "from_file"))
        out["extrinsics"] = ExtrinsicsError(
            number(e.get("translation_sigma_m", 0.0), ew.child("translation_sigma_m", e), min=0, max=1),
            number(e.get("rotation_sigma_deg", 0.0), ew.child("rotation_sigma_deg", e), min=0, max=30),
            _file(e, ew, root, ("translation_sigma_m", "rotation_sigma_deg")))
    if "fisheye_intrinsics" in v:
        iw = where.child("fisheye_intrinsics", v)
        keys = ("focal_rel_sigma", "center_sigma_px", "xi_sigma")
        i = mapping(v["fisheye_intrinsics"], iw, (), keys + ("from_file",))
        out["fisheye_intrinsics"] = IntrinsicsError(
            number(i.get("focal_rel_sigma", 0.0), iw.child("focal_rel_sigma", i), min=0, max=0.5),
            number(i.get("center_sigma_px", 0.0), iw.child("center_sigma_px", i), min=0, max=100),
            number(i.get("xi_sigma", 0.0), iw.child("xi_sigma", i), min=0, max=1),
            _file(i, iw, root, keys))
    if "clock_offset_s" in v:
        out["clock_offset_s"] = number(v["clock_offset_s"], where.child("clock_offset_s", v), min=-1, max=1)
    return Given(integer(v["seed"], where.child("seed", v), min=0), **out)


def _file(block: dict, where: Where, root: Path, exclusive: tuple[str, ...]) -> Path | None:
    if "from_file" not in block:
        return None
    fw = where.child("from_file", block)
    if clash := [k for k in exclusive if k in block]:
        raise fw.error(f"from_file excludes {', '.join(clash)}")
    path = root / string(block["from_file"], fw)
    if not path.is_file():
        raise fw.error(f"file not found: {path}")
    return path
