"""Publisher endpoints: the lossy twin of every endpoint, per-policy choice, IPv6 hosts."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np
import zmq

from probeless.launch.graph import Graph, NodeDecl
from probeless.launch.validate import host_endpoint
from probeless.messages import Header, Image
from probeless.runtime.queues import InputQueue
from probeless.runtime.receiver import InputWire, Receiver
from probeless.runtime.transport import Publisher, endpoint_for_policy, lossy_endpoint


def test_lossy_twin_and_policy_choice():
    assert lossy_endpoint("ipc:///tmp/run/3.pub") == "ipc:///tmp/run/3.lossy"
    assert lossy_endpoint("tcp://10.0.0.2:7402") == "tcp://10.0.0.2:7403"
    assert lossy_endpoint("tcp://[::1]:7400") == "tcp://[::1]:7401"
    assert endpoint_for_policy("tcp://h:7400", "block") == "tcp://h:7400"
    assert {endpoint_for_policy("tcp://h:7400", p) for p in ("latest", "drop_oldest")} == {"tcp://h:7401"}


def test_hosts_take_two_ports_per_node_and_ipv6_addresses_get_brackets():
    g = Graph(file="g.yaml")
    g.hosts = {"cam": {"address": "::1", "port_base": 7400}}
    for nid in ("a", "b"):
        g.nodes[nid] = NodeDecl(id=nid, node="pattern_source", file="g.yaml", line=1, host="cam")
    assert [host_endpoint(g, d) for d in g.nodes.values()] == ["tcp://[::1]:7400", "tcp://[::1]:7402"]


def test_messages_cross_an_ipv6_endpoint():
    with socket.socket(socket.AF_INET6) as s:
        s.bind(("::1", 0))
        port = s.getsockname()[1]
    ctx = zmq.Context()
    pub = Publisher(ctx, f"tcp://[::1]:{port}", "src")
    queues = {"image": InputQueue("image", "drop_oldest", 100)}
    rx = Receiver(ctx, [InputWire("image", endpoint_for_policy(f"tcp://[::1]:{port}", "drop_oldest"), "src/image",
                                  None)], queues, threading.Condition(), "inproc://wake-v6")
    rx.start()
    wake = ctx.socket(zmq.PAIR)
    wake.connect("inproc://wake-v6")
    try:
        deadline = time.monotonic() + 10
        while not pub.subscriptions["src/image"] and time.monotonic() < deadline:
            pub.poll_subscriptions(50)
        for i in range(10):
            pub.publish("src/image", Image(Header(i, "x"), np.full((4, 4, 1), i, np.uint8), "mono8"), lambda: False)
        while queues["image"].received < 10 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert [m.data[0, 0, 0] for _, m in queues["image"].items] == list(range(10))
    finally:
        rx.stop(wake)
        rx.join(2)
        wake.close(0)
        pub.close()
        ctx.term()
