"""360° video IBL nodes: panorama sources, inverse tone mapping, diffuse radiance maps."""
