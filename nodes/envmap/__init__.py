"""Environment-map nodes: the cubemap renderer and the paper's baseline (one swaps for the other)."""
