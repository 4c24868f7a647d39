"""The small envmap sweep on a local Ray (2 CPUs) gives the same table as the local process pool."""

from __future__ import annotations

import pytest
from sweep_common import SCENES, read_csv, values, write_sweep

from probeless.sweep.driver import run_sweep

ray = pytest.importorskip("ray")

pytestmark = [pytest.mark.slow, pytest.mark.gl, pytest.mark.graph]


def test_ray_gives_the_same_table_as_the_pool(tmp_path):
    sweep = write_sweep(tmp_path / "small.yaml", scenes=SCENES[:1])  # 1 scene x 2 methods: a run per CPU
    pool = run_sweep(sweep, tmp_path / "pool", jobs=2, show_progress=False)
    ray.init(num_cpus=2, include_dashboard=False)
    try:
        on_ray = run_sweep(sweep, tmp_path / "ray", ray="auto", show_progress=False)
        assert ray.is_initialized()  # a Ray the caller started is left running
    finally:
        ray.shutdown()
    assert (pool.ok, on_ray.ok, on_ray.failed) == (2, 2, 0)
    assert on_ray.ray_startup_s == 0.0
    assert values(read_csv(tmp_path / "ray" / "results.csv")) == values(read_csv(tmp_path / "pool" / "results.csv"))
