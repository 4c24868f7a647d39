"""The methods and metrics of the envmap evaluation (:mod:`probeless.envmap.evaluate`), as plain names.

A module of its own so that the command line (``probeless eval envmap --methods``) can offer them
without importing the evaluation (GL, the coarse model, matplotlib) for every ``probeless`` command.
"""

from __future__ import annotations

METHODS = ("ours", "baseline", "baseline_dense", "no_inpainting", "no_brightness", "no_dense", "no_occlusion")
# coarse-model variant each method needs (None: the baseline map)
VARIANT = {"ours": "full", "no_dense": "full", "no_inpainting": "no_inpainting", "no_brightness": "no_brightness",
           "no_occlusion": "no_occlusion", "baseline": None, "baseline_dense": None}
# probeless.envmap.score.SCORES (common texels, HDR truth, SH against the truth's SH), then the earlier whole-map ones
METRICS = ("psnr_common", "ssim_common", "coverage", "common_coverage", "psnr_all", "rmse_sa", "log_rmse_hdr",
           "pu21_psnr", "sh_diffuse_error", "sh_diffuse_error_ldr",
           "envmap_psnr", "envmap_ssim", "mirror_psnr", "diffuse_psnr", "sh_rel_error")
TABLE = METRICS[:10]  # the columns of the text table (all of METRICS are in the JSON)
