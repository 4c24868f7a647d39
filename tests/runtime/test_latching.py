"""Latched topics, in one process: which outputs are latched (defaults, the graph's ``latched:`` key, replays),
and what the sockets deliver (a late joiner gets the last latched message, an early one never gets it twice).

The real-process tests (late graph, node restarted downstream of a replay) are tests/faults/test_latched_topics.py.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import zmq

from probeless.launch.launcher import load_checked
from probeless.launch.plan import build_plan
from probeless.launch.replay import add_player
from probeless.messages import Header, Image
from probeless.messages.geometry import Floorplan
from probeless.runtime.latching import is_latched, parse_latched
from probeless.runtime.queues import InputQueue
from probeless.runtime.receiver import InputWire, Receiver
from probeless.runtime.transport import Publisher


@pytest.mark.parametrize("output,overrides,expected", [
    ("floorplan", {}, True), ("fisheye_from_rgbd", {}, True), ("rgbd/camera_info", {}, True),
    ("rig/floorplan", {}, True),           # a replay's output is the recorded topic
    ("rgb", {}, False), ("floorplan_debug", {}, False), ("gt/rgbd_pose", {}, False),
    ("rgb", {"rgb": True}, True), ("rgbd/camera_info", {"rgbd/camera_info": False}, False),
    ("gt/a", {"gt/*": True}, True), ("gt/a", {"gt/*": True, "gt/a": False}, False),
    ("fisheye/camera_info", {"*": False, "*/camera_info": True}, True),  # the longer glob wins
])
def test_which_outputs_are_latched(output, overrides, expected):
    assert is_latched(output, overrides) is expected


@pytest.mark.parametrize("value", [["a", 1], {"a": "yes"}, "floorplan", [""], True])
def test_a_malformed_latched_key_is_refused(value):
    got, problem = parse_latched(value)
    assert got == {} and problem.startswith("'latched' must be a list of output names")


def _graph(tmp_path, latched: str = ""):
    path = tmp_path / "g.yaml"
    path.write_text(f"""nodes:
  - id: cam
    node: pattern_source
    inputs: {{tick: timer/hz/10}}
    params: {{count: 2}}
{latched}  - id: sink
    node: summary_sink
    inputs: {{image: {{source: cam/image, policy: block}}}}
    params: {{out_dir: {tmp_path}/summary}}
""")
    return load_checked(str(path), {})


def test_the_plan_marks_latched_outputs_and_a_replay_keeps_the_graph_s_choice(tmp_path):
    plan = build_plan(_graph(tmp_path), tmp_path)
    assert plan["nodes"]["cam"]["outputs"]["image"]["latched"] is False  # not a default name
    graph = _graph(tmp_path, "    latched: [image]\n")
    assert build_plan(graph, tmp_path)["nodes"]["cam"]["outputs"]["image"]["latched"] is True
    add_player(graph, "rec.mcap", {"cam/image": "sensor/Image"})  # the replay stands in for cam
    player = build_plan(graph, tmp_path)["nodes"]["bag_player"]
    assert player["outputs"]["cam/image"]["latched"] is True


def _receiver(zctx, endpoint: str, topics: list[str], name: str):
    wires = [InputWire(t, endpoint, t, None) for t in topics]
    queues = {t: InputQueue(t, "drop_oldest", 10) for t in topics}
    rx = Receiver(zctx, wires, queues, threading.Condition(), f"inproc://wake-{name}", node_id=name)
    wake = zctx.socket(zmq.PAIR)
    wake.connect(f"inproc://wake-{name}")
    rx.start()
    return rx, queues, wake


def _messages(queues, name: str) -> list:
    return [m for _, m in queues[name].items]


def _until(cond, pub: Publisher, timeout_s: float = 5.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and not cond():
        pub.serve_late_joiners(lambda: False)  # what the node loop does every 20 ms
        time.sleep(0.01)


def test_a_late_subscriber_gets_the_last_latched_message_once_and_no_other(tmp_path):
    zctx = zmq.Context()
    endpoint = f"ipc://{tmp_path}/p.pub"
    pub = Publisher(zctx, endpoint, "rig", latched={"rig/floorplan"})
    topics = ["rig/floorplan", "rig/image"]
    early, early_q, early_wake = _receiver(zctx, endpoint, topics, "early")
    try:
        _until(lambda: pub.subscriptions["rig/floorplan"] >= 1 and pub.subscriptions["rig/image"] >= 1, pub)
        stop = lambda: False  # noqa: E731
        plans = [Floorplan(Header(i, "world"), np.array([[0, 0], [w, 0], [w, 2.0]]), 2.5) for i, w in enumerate((3, 4))]
        for plan in plans:
            pub.publish("rig/floorplan", plan, stop)
        pub.publish("rig/image", Image(Header(0, "cam"), np.zeros((2, 2, 1), np.uint8), "mono8"), stop)
        _until(lambda: len(early_q["rig/floorplan"].items) == 2 and len(early_q["rig/image"].items) == 1, pub)
        late, late_q, late_wake = _receiver(zctx, endpoint, topics, "late")
        try:
            _until(lambda: late_q["rig/floorplan"].items, pub)
            _until(lambda: False, pub, 0.3)  # room for anything else that would (wrongly) come
            got = _messages(late_q, "rig/floorplan")
            assert len(got) == 1 and got[0].header.seq == 1  # the last one only
            np.testing.assert_array_equal(got[0].vertices, plans[1].vertices)
            assert not late_q["rig/image"].items  # not latched: never re-sent
            assert [m.header.seq for m in _messages(early_q, "rig/floorplan")] == [0, 1]  # no second copy
            assert pub.resent["rig/floorplan"] == 1 and pub.published["rig/floorplan"] == 2
        finally:
            late.stop(late_wake)
            late.join(2)
            late_wake.close(0)
    finally:
        early.stop(early_wake)
        early.join(2)
        early_wake.close(0)
        pub.close()
        zctx.term()
