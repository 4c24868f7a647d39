"""Environment-map nodes: cubemap renderer, baseline, IBL compositor."""
