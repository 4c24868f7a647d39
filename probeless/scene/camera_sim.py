"""One colour camera of the rig with its ``sensor_effects``: linear radiance in, uint8 codes out.

Per frame: exposure (fixed, or auto-exposure lagging the previous frame's metering) x white-balance
gains x vignetting -> Poisson-Gaussian noise -> clip to the full well -> response curve -> 8 bits.
"""

from __future__ import annotations

import numpy as np

from probeless.scene.effects_spec import CameraEffects
from probeless.scene.sensor_effects import (
    auto_exposure_step,
    converged_exposure,
    encode,
    metered_mean,
    poisson_gaussian,
    response_lut,
    vignetting_map,
)


class CameraSim:
    """The state of one camera (its auto-exposure) across the frames of a sequence rendered in time order.

    ``cos_theta`` (H, W): cosine of each pixel's angle to the optical axis; ``center`` (cx, cy) [px];
    ``mask`` (H, W) bool: pixels that see the scene (metering ignores the rest).
    """

    def __init__(self, effects: CameraEffects, exposure: float, cos_theta: np.ndarray,
                 center: tuple[float, float], mask: np.ndarray | None, seed: tuple[int, ...]):
        self.effects, self.nominal, self.mask, self.seed = effects, exposure, mask, seed
        self.lut = response_lut(effects.gamma)
        self.wb = None if effects.wb_gains is None else np.asarray(effects.wb_gains, np.float32)
        gain = vignetting_map(effects.vignetting, cos_theta, center) if effects.vignetting else None
        if self.wb is not None:
            gain = self.wb if gain is None else gain * self.wb
        self.gain = gain  # per-pixel white balance x vignetting, (3,) or (H, W, 1 | 3); None = 1
        self.outside = None if mask is None else ~mask  # pixels that stay black (outside the image circle)
        self.exposure = exposure   # effective exposure of the last recorded frame [-]
        self._last: tuple[float, float] | None = None  # (t, metered mean) of the last frame

    def reset(self) -> None:
        """Forget the auto-exposure history (the next frame starts converged)."""
        self._last = None

    def gains(self) -> np.ndarray:
        """(3,) float32 per-channel multiplier of the last frame: exposure x white balance."""
        wb = np.ones(3, np.float32) if self.wb is None else self.wb
        return (np.float32(self.exposure) * wb).astype(np.float32)

    def _update_exposure(self, radiance: np.ndarray, t: float) -> None:
        ae = self.effects.auto_exposure
        if ae is None:
            return
        if self._last is None or t <= self._last[0]:
            self.exposure = converged_exposure(metered_mean(radiance, self.mask), ae)
        else:
            self.exposure = auto_exposure_step(self.exposure, self._last[1], t - self._last[0], ae)
        self._last = (t, metered_mean(radiance, self.mask))

    def record(self, radiance: np.ndarray, t: float, index: int) -> np.ndarray:
        """uint8 (H, W, 3) image of linear ``radiance`` (H, W, 3) captured at time ``t`` (frame ``index``)."""
        self._update_exposure(radiance, t)
        signal = radiance if self.gain is None else radiance * self.gain
        if self.effects.noise is None:  # exposure applied while encoding: identical to the plain rig without effects
            return encode(signal, self.lut, self.exposure)
        noisy = poisson_gaussian(signal, self.effects.noise, np.random.default_rng((*self.seed, index)), self.exposure)
        image = encode(noisy, self.lut)
        if self.outside is not None:  # outside the image circle stays black despite the read noise
            image[self.outside] = 0
        return image

    def ideal(self, radiance: np.ndarray) -> np.ndarray:
        """uint8 codes of ``radiance`` with the last frame's exposure, white balance and response, no noise or
        vignetting (what ``gt/envmap_ldr`` shows)."""
        return encode(radiance if self.wb is None else radiance * self.wb, self.lut, self.exposure)
