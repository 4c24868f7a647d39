"""Scene-file blocks that make the synthetic rig less ideal: ``sensor_effects`` and ``given``.

Every effect is off unless its key is present; a scene without these blocks renders exactly as
before. Units and what each parameter models are documented in docs/scene/README.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class AutoExposure:
    """First-order-lag auto-exposure metering the mean luminance of the previous frame."""

    target: float = 0.18    # wanted mean linear luminance of the exposed signal [0..1]
    tau_s: float = 0.3      # time constant of the lag in log exposure [s]; 0 = immediate
    min: float = 0.01       # exposure multiplier limits [-]
    max: float = 16.0


@dataclass(frozen=True)
class Vignetting:
    """Relative illumination falloff: ``cos4`` (cos^4 of the ray's angle to the optical axis) or
    ``poly`` (1 + k1 r^2 + k2 r^4 + k3 r^6, r = distance from the principal point / half the
    diagonal between the corner pixels' centres)."""

    model: str = "cos4"
    coeffs: tuple[float, ...] = ()


@dataclass(frozen=True)
class Noise:
    """Poisson-Gaussian sensor noise on the linear exposed signal (1 = full well)."""

    full_well: float          # electrons at saturation; shot-noise variance = signal / full_well [e-]
    read_sigma: float = 0.0   # read noise standard deviation [fraction of full scale]


@dataclass(frozen=True)
class CameraEffects:
    """Effects of one colour camera (the RGB-D colour stream or the fisheye)."""

    auto_exposure: AutoExposure | None = None
    wb_gains: tuple[float, float, float] | None = None  # white-balance error: per-channel gains [-]
    vignetting: Vignetting | None = None
    gamma: float | None = None             # response curve x^(1/gamma) instead of sRGB; None = sRGB
    noise: Noise | None = None
    exposure_time_s: float = 0.01          # shutter time, over which light flicker is averaged [s]


@dataclass(frozen=True)
class Flicker:
    """Mains flicker of the ceiling lights: radiance x (1 + amplitude cos(2 pi f t + phase))."""

    amplitude: float          # modulation depth [0..1]
    frequency_hz: float = 100.0
    phase_deg: float = 0.0


@dataclass(frozen=True)
class KinectDepth:
    """Structured-light depth errors (Khoshelham & Elberink 2012, Kinect v1)."""

    sigma_k: float = 0.0              # sigma_z = sigma_k * z^2 [1/m]
    baseline_m: float = 0.075         # projector-camera baseline [m]
    focal_px: float = 580.0           # IR camera focal length [px]
    disparity_step_px: float = 0.0    # disparity quantum [px] (Kinect v1: 1/8); 0 = no quantisation
    max_incidence_deg: float = 90.0   # drop pixels whose surface is seen at a larger angle from its normal [deg]
    edge_jump_m: float = 0.1          # neighbour depth step that counts as a discontinuity, per metre of z [m/m]
    edge_dropout: float = 0.0         # probability a pixel at a discontinuity is dropped [0..1]
    flying_pixels: float = 0.0        # probability a pixel at a discontinuity takes a depth between both sides [0..1]


@dataclass(frozen=True)
class SensorEffects:
    """The ``sensor_effects`` block."""

    seed: int = 0
    rgbd: CameraEffects = CameraEffects()
    fisheye: CameraEffects = CameraEffects()
    flicker: Flicker | None = None
    depth: KinectDepth | None = None


@dataclass(frozen=True)
class FloorplanError:
    """What is wrong with the floorplan handed to the pipeline."""

    vertex_sigma_m: float = 0.0   # per-coordinate Gaussian offset of every vertex [m]
    rotation_deg: float = 0.0     # rotation of the whole plan about its centroid [deg, counter-clockwise]
    ceiling_m: float = 0.0        # added to the ceiling height [m]


@dataclass(frozen=True)
class ExtrinsicsError:
    """A perturbed fisheye_from_rgbd (per-axis Gaussian), or the one in a calibration file."""

    translation_sigma_m: float = 0.0
    rotation_sigma_deg: float = 0.0
    from_file: Path | None = None


@dataclass(frozen=True)
class IntrinsicsError:
    """Perturbed fisheye intrinsics (Gaussian), or a calibration file's (`probeless calibrate fisheye`)."""

    focal_rel_sigma: float = 0.0   # relative error of fx and fy [-]
    center_sigma_px: float = 0.0   # error of cx and cy [px]
    xi_sigma: float = 0.0          # error of the omnidir xi [-]
    from_file: Path | None = None


@dataclass(frozen=True)
class Given:
    """The ``given`` block: what the pipeline is told (rendering always uses the truth)."""

    seed: int = 0
    floorplan: FloorplanError | None = None
    extrinsics: ExtrinsicsError | None = None
    fisheye_intrinsics: IntrinsicsError | None = None
    clock_offset_s: float = 0.0    # added to every fisheye stamp, unknown to the graph [s]
