"""Write tests/durations.json, the seconds each test file took in a full run, from pytest's JUnit XML.

tests/conftest.py hands the files to the pytest-xdist workers longest first by these figures. Refresh after a
change that moves a file's time a lot:

    .venv/bin/python -m pytest -q -n 2 --dist loadfile --junitxml=/tmp/junit.xml
    .venv/bin/python tools/test_durations.py /tmp/junit.xml
"""

from __future__ import annotations

import argparse
import json
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

TESTS = Path(__file__).resolve().parent.parent / "tests"


def file_seconds(junit: Path) -> dict[str, float]:
    """{path relative to tests/: summed test seconds (set-up, call, tear-down)} of a JUnit XML report."""
    seconds: Counter[str] = Counter()
    for case in ET.parse(junit).iter("testcase"):
        module = case.get("classname") or ""
        parts = module.split(".")
        if parts and parts[0] == "tests":
            parts = parts[1:]
        while parts and not (TESTS.joinpath(*parts).with_suffix(".py")).is_file():
            parts = parts[:-1]  # a test class: its module is the prefix
        if parts:
            seconds["/".join(parts) + ".py"] += float(case.get("time") or 0.0)
    return dict(seconds)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("junit", type=Path, help="pytest --junitxml report of a full run")
    ap.add_argument("-o", "--output", type=Path, default=TESTS / "durations.json")
    ns = ap.parse_args(argv)
    secs = file_seconds(ns.junit)
    ordered = {k: round(v, 1) for k, v in sorted(secs.items(), key=lambda kv: -kv[1]) if v >= 1.0}
    ns.output.write_text(json.dumps(ordered, indent=1) + "\n")
    print(f"{len(ordered)} files, {sum(secs.values()):.0f} s in all -> {ns.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
