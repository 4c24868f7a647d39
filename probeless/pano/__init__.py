"""Real-time image-based lighting from LDR 360° video (paper 002): inverse tone mapping, diffuse radiance maps,
glossy ring sampling."""
