"""The launcher's quiescence check for lockstep replay (probeless.launch.lockstep): the double collect, and how
long it waits before asking again."""

from __future__ import annotations

from probeless.launch.lockstep import QuiescenceCheck

PLAN = {"nodes": {"player": {"inputs": []},
                  "sink": {"inputs": [{"name": "image", "topic": "player/image", "source_node": "player"}]}}}


def snap(busy=False, queued=0, received=1):
    return {"busy": busy, "queued": queued, "received": {"image": received}, "published": {}}


def test_quiet_needs_two_identical_quiet_collects_and_the_confirming_one_is_immediate():
    check = QuiescenceCheck(PLAN, "player", {"player/image": 1})
    check.begin_round(["player", "sink"])
    assert check.add_reply("sink", 1, snap()) and not check.quiet()    # quiet once: not yet confirmed
    assert check.retry_delay_s() == 0.0                                 # confirm at once
    check.begin_round(["player", "sink"])
    assert check.add_reply("sink", 2, snap()) and check.quiet()


def test_a_busy_graph_is_asked_again_after_a_growing_capped_delay_however_long_it_works():
    check = QuiescenceCheck(PLAN, "player", {"player/image": 1})
    delays = []
    for round_id in range(1, 3001):                                     # a stage busy for thousands of collects
        check.begin_round(["sink"])
        check.add_reply("sink", round_id, snap(busy=True))
        assert not check.quiet()
        delays.append(check.retry_delay_s())
    assert delays[:6] == [0.00025, 0.0005, 0.001, 0.002, 0.004, 0.008] and max(delays) == 0.008
    check.begin_round(["sink"])
    check.add_reply("sink", 3001, snap(received=0))                     # in flight: an edge is not balanced
    assert not check.quiet() and check.retry_delay_s() == 0.008
