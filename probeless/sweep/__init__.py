"""`probeless sweep`: grids of graph variants and evaluations over scenes and recordings, locally or on Ray."""
