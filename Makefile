# The two commands of the README. Each does all set-up itself, idempotently.
.PHONY: demo test test-fast lint setup bench clean

setup:
	@bash tools/setup.sh

demo: setup
	.venv/bin/probeless scene preview launch/scenes/l_shaped_lounge.yaml --t 2.0 -o out/demo/scene_preview.png
	.venv/bin/probeless launch launch/synthetic_rig.yaml out_dir:=out/demo/rig
	.venv/bin/probeless scene render launch/scenes/l_shaped_lounge.yaml --duration 2 -o out/demo/lounge_2s.mcap --force
	.venv/bin/probeless bag info out/demo/lounge_2s.mcap
	.venv/bin/probeless graph launch/synthetic_rig.yaml --out out/demo/graph.png
	.venv/bin/probeless launch launch/coarse_model.yaml out_dir:=out/demo/coarse
	.venv/bin/probeless coarse preview launch/scenes/partition_room.yaml --duration 4 -o out/demo/coarse_preview
	.venv/bin/probeless launch launch/probeless.yaml seconds:=5 out_dir:=out/demo/pipeline
	.venv/bin/probeless launch launch/pbgi.yaml out_dir:=out/demo/pbgi
	.venv/bin/probeless eval envmap launch/scenes/l_shaped_lounge.yaml --oracle --duration 5 --stride 2 --figures out/demo/figures --plot out/demo/figures/envmap_psnr.png > out/demo/accuracy.txt
	cat out/demo/accuracy.txt
	.venv/bin/probeless bench pipeline --quick > out/demo/timing.txt
	cat out/demo/timing.txt
	@if [ -f ../shared/data/video360/bled_lake_360_timelapse_720p_vp9.webm ]; then \
		.venv/bin/probeless launch launch/pano360_ibl.yaml out_dir:=out/demo/pano360; \
	else echo "pano360: ../shared/data/video360/ not found: the 360° video IBL graph is skipped"; fi

lint: setup
	.venv/bin/ruff check probeless messages nodes tests tools
	.venv/bin/lint-imports

# on pytest-xdist workers, a module per worker at a time (tests/conftest.py: order, timing-sensitive tests alone)
PYTEST_WORKERS ?= 2
PYTEST_XDIST = -n $(PYTEST_WORKERS) --dist loadfile

test: lint
	.venv/bin/python -m pytest -q $(PYTEST_XDIST)

# the inner loop: everything not marked slow (see the README for its time)
test-fast: lint
	.venv/bin/python -m pytest -q $(PYTEST_XDIST) -m "not slow"

bench: setup
	.venv/bin/probeless bench bus

clean:
	rm -rf out .pytest_cache
