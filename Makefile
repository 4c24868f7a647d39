# The two commands of the README. Each does all set-up itself, idempotently.
.PHONY: demo test setup bench clean

setup:
	@bash tools/setup.sh

demo: setup
	.venv/bin/probeless launch launch/demo_runtime.yaml
	.venv/bin/probeless graph launch/demo_runtime.yaml --out out/demo/graph.png

test: setup
	.venv/bin/python -m pytest -q

bench: setup
	.venv/bin/probeless bench bus

clean:
	rm -rf out .pytest_cache
