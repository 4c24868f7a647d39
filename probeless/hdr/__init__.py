"""HDR expansion of LDR coloured point clouds from one uncalibrated HDR photo (paper 001, §4).

Stages, each a pure function: views of the cloud by GPU point splatting with an id buffer, placed
automatically over the clusters of saturated points (:mod:`.splat`, :mod:`.views`); exposure matching
of the photo to the cloud (:mod:`.exposure`); per-view transfer by inverse tone mapping or
generalized PatchMatch, back to the points (:mod:`.transfer`, :mod:`.patchmatch`); and Poisson
filling of the points left without a valid value (:mod:`.poisson`).
"""
