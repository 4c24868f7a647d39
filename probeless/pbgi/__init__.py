"""Point-based global illumination of (HDR) point clouds (paper 001, §5): the bounding sphere hierarchy
(:mod:`.bsh`, §5.1 and the 40-byte GPU node of §5.4), BRDFs and materials (:mod:`.brdf`, :mod:`.materials`), the
objects' G-buffer and its cone mip-map (:mod:`.gbuffer`), the Classic / Mipmapped / Hybrid micro-buffer traversals
and Eq. 9 shading (:mod:`.microbuffer`), and the renderer tying them together (:mod:`.render`)."""
