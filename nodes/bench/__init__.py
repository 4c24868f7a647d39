"""Nodes the benchmarks launch (``probeless.bench``): ``bench_source``/``bench_sink`` of the bus benchmark,
``bench_camera_source``, ``bench_timing_source``, ``bench_timing_sink``, ``bench_jitter_worker`` of the
recording benchmark."""
