"""Environment maps per virtual object: cubemap rendering from the coarse and dense models, SH projection,
baseline (paper §4.7, §5.3)."""
