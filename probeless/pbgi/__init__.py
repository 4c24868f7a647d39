"""Point-based global illumination of HDR point clouds (paper 001, §5): the bounding sphere hierarchy
(:mod:`.bsh`, §5.1 and the 40-byte GPU node of §5.4)."""
