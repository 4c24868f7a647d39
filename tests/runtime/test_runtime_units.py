"""Pure runtime pieces: params, queue policies, timers, and nodes run without a bus."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
import pytest

from probeless.errors import ParamError
from probeless.messages import Header, Tick
from probeless.nodes.demo.pattern import PatternSource, pattern_image
from probeless.nodes.demo.summary import SummarySink, summarize
from probeless.nodes.demo.transform import ImageTransform, transform_image
from probeless.runtime import param
from probeless.runtime.params import check_params, load_params
from probeless.runtime.queues import InputQueue
from probeless.runtime.testing import run_node
from probeless.runtime.timers import TimerSet


@dataclass(frozen=True)
class P:
    rate: float = param(1.0, min=0.0, max=10.0)
    name: str = param("x")
    mode: Literal["a", "b"] = "a"
    matrix: tuple[tuple[float, ...], ...] = ((1.0, 0.0), (0.0, 1.0))
    limit: int | None = None
    flag: bool = False


def test_params_convert_and_default():
    p = load_params(P, {"rate": 2, "matrix": [[1, 2], [3, 4]], "limit": 5}, node_id="n")
    assert p.rate == 2.0 and isinstance(p.rate, float)
    assert p.matrix == ((1.0, 2.0), (3.0, 4.0)) and p.limit == 5 and p.mode == "a"


@pytest.mark.parametrize("values, key, text", [
    ({"rte": 1.0}, "rte", "unknown parameter"),
    ({"rate": "fast"}, "rate", "expected float"),
    ({"rate": 11}, "rate", "above the maximum 10.0"),
    ({"rate": float("nan")}, "rate", "expected float"),
    ({"mode": "c"}, "mode", "expected 'a' | 'b'"),
    ({"flag": 1}, "flag", "expected bool"),
    ({"limit": 2.5}, "limit", "expected int | NoneType"),
    ({"matrix": [[1, "x"]]}, "matrix", "expected list of list of float"),
])
def test_param_errors_name_node_key_and_line(values, key, text):
    errors = check_params(P, values, node_id="cam", file="g.yaml", lines={key: 12})
    assert len(errors) == 1
    assert errors[0].format().startswith(f"g.yaml:12: node 'cam': key '{key}': ")
    assert text in errors[0].message
    with pytest.raises(ParamError):
        load_params(P, values, node_id="cam")


@dataclass(frozen=True)
class Q:
    size: tuple[int, ...] = param((4, 2), length=2, min=1)
    pose: tuple[float, ...] = param((), length=(0, 7), finite=True)
    spec: tuple[Any, ...] = param((), finite=True)
    codec: str = param("mp4v", length=4)
    names: tuple[str, ...] = param((), min_length=1, max_length=2, check=lambda v: "no spaces" if any(
        " " in n for n in v) else None)
    counts: tuple[int, ...] = param((), check=lambda v, p: None if len(v) == len(p.names) else "one per name")
    scene: str = param("", path="file", must_exist=True)
    folder: str = param(".", path="dir", must_exist=True)


@pytest.mark.parametrize("values, key, text", [
    ({"size": [4, 2, 1]}, "size", "needs 2 value(s), got 3: [4, 2, 1]"),
    ({"size": [4, 0]}, "size", "item [1]: 0 is below the minimum 1"),
    ({"pose": [0, 0, 0]}, "pose", "needs 0 or 7 value(s), got 3"),
    ({"pose": [0, 0, float("inf"), 0, 0, 0, 1]}, "pose", "item [2]: inf is not finite (expected list of float)"),
    ({"spec": [{"position": [1, float("nan"), 0]}]}, "spec", "item [0]['position'][1]: nan is not finite"),
    ({"codec": "mp4"}, "codec", "needs 4 character(s), got 3"),
    ({"names": []}, "names", "needs at least 1 value(s), got 0"),
    ({"names": ["a b"]}, "names", "no spaces"),
    ({"names": ["a", "b"], "counts": [1]}, "counts", "one per name"),
    ({"scene": "no/such.yaml"}, "scene", "no/such.yaml: file not found (relative to the working folder"),
    ({"scene": "."}, "scene", ".: is a folder, not a file"),
    ({"folder": "no_such_dir"}, "folder", "no_such_dir: folder not found"),
])
def test_param_declared_rules(values, key, text):
    errors = check_params(Q, values, node_id="n", file="g.yaml", lines={key: 3})
    assert [e.key for e in errors] == [key], errors
    assert errors[0].format().startswith(f"g.yaml:3: node 'n': key '{key}': ") and text in errors[0].message, errors
    with pytest.raises(ParamError):
        load_params(Q, values, node_id="n")


def test_param_paths_are_relative_to_the_working_folder(tmp_path, monkeypatch):
    (tmp_path / "scene.yaml").write_text("x")
    assert check_params(Q, {"scene": str(tmp_path / "scene.yaml")}, node_id="n") == []
    monkeypatch.chdir(tmp_path)
    assert check_params(Q, {"scene": "scene.yaml", "folder": "."}, node_id="n") == []
    assert check_params(Q, {"scene": ""}, node_id="n") == []  # the empty default: not given
    assert load_params(Q, {"names": ["a"], "counts": [2]}, node_id="n").counts == (2,)


def test_param_declaration_errors():
    with pytest.raises(TypeError, match="must_exist"):
        param("", must_exist=True)
    with pytest.raises(TypeError, match="path="):
        param("", path="folder")


def test_required_param():
    @dataclass(frozen=True)
    class R:
        path: str = param()
    assert "required parameter is missing" in check_params(R, {}, node_id="n")[0].message


@pytest.mark.parametrize("policy, size, expect_items, expect_dropped", [
    ("latest", 1, [4], 4), ("drop_oldest", 3, [2, 3, 4], 2), ("block", 3, [0, 1, 2], 0)])
def test_queue_policies(policy, size, expect_items, expect_dropped):
    q = InputQueue("in", policy, size)
    accepted = [q.push(i, i, seq=i) for i in range(5)]
    assert [m for _, m in q.items] == expect_items
    assert q.dropped == expect_dropped
    assert accepted == ([True] * 3 + [False] * 2 if policy == "block" else [True] * 5)
    assert q.received == sum(accepted)


def test_queue_counts_seq_gaps_and_publisher_restart():
    q = InputQueue("in", "drop_oldest", 100)
    for seq in (0, 1, 4, 5, 9, 0, 1):   # 2 missing, then 3 missing, then the publisher restarted
        q.push(seq, seq, seq=seq)
    assert q.seq_gaps == 5


def test_timers_skip_missed_periods_instead_of_bursting():
    fired = []
    timers = TimerSet()
    timers.add(10, "t", lambda missed: fired.append(missed), start_ns=0)
    assert timers.next_deadline() == 10
    assert [m for _, m in timers.pop_due(10)] == [0]
    assert [m for _, m in timers.pop_due(55)] == [3]     # deadlines 20..50 passed: fired once, 3 missed
    assert timers.next_deadline() == 60                   # stays on the 10 ns grid
    assert timers.pop_due(59) == []


def test_demo_nodes_without_a_bus(tmp_path):
    ticks = [("tick", Tick(Header(1000 + i), 33)) for i in range(5)]
    src = run_node(PatternSource, ticks, {"width": 64, "height": 48, "count": 3})
    images = src.outputs("image")
    assert len(images) == 3 and src.stopped                    # stops itself after count
    np.testing.assert_array_equal(images[2].data, pattern_image(64, 48, 2))
    assert images[2].header.stamp_ns == 1002

    fx = run_node(ImageTransform, [("image", m) for m in images], {"operation": "blur", "ksize": 3})
    ref = cv2.GaussianBlur(images[0].data, (3, 3), 0)           # independent OpenCV reference
    np.testing.assert_array_equal(fx.outputs("image")[0].data, ref)

    run_node(SummarySink, [("image", m) for m in fx.outputs("image")], {"out_dir": str(tmp_path)})
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["frames"] == 3
    assert cv2.imread(str(tmp_path / "last_frame.png")).shape == (48, 64, 3)


def test_pattern_is_analytic():
    img = pattern_image(256, 256, 0)
    assert img[0, 255, 0] == 255 and img[255, 0, 1] == 255 and img[0, 0, 2] == 255  # ramps and square at origin


def test_transform_operations_match_opencv():
    rgb = pattern_image(40, 30, 3)
    assert np.array_equal(transform_image(rgb, "invert"), 255 - rgb)
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    assert np.array_equal(transform_image(rgb, "gray")[..., 1], gray)
    assert np.array_equal(transform_image(rgb, "edges")[..., 0], cv2.Canny(gray, 50, 150))


def test_summarize_counts_gaps_and_rate():
    s = summarize([0, 100_000_000, 200_000_000], [1.0, 2.0, 3.0], [0, 1, 4])
    assert s["seq_gaps"] == 2 and s["rate_hz"] == pytest.approx(10.0) and s["latency_ms_p50"] == 2.0
