"""rosbag2's own public test bags (tests/data/rosbag2/, Apache-2.0): empty bags, service events, lone files.

References are independent of our code: each bag's metadata.yaml (written by rosbag2 when it recorded the
bag) and, for lone files, rosbags' own low-level reader.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

pytest.importorskip("rosbags")

from probeless.bag.reader import BagReader  # noqa: E402
from probeless.bag.ros_source import RosBag  # noqa: E402
from probeless.cli import main  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / "data" / "rosbag2"
BAGS = sorted(p for p in DATA.iterdir() if p.is_dir() or p.suffix in (".mcap", ".db3"))


def _reference_counts(bag: Path) -> dict[str, int]:
    """{topic: messages} from rosbag2's metadata.yaml, or from rosbags' low-level reader for a lone file."""
    if bag.is_dir():
        info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        return {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    from rosbags.rosbag2 import Reader
    with Reader(bag) as r:
        counts = {c.topic: 0 for c in r.connections}
        for conn, _, _ in r.messages():
            counts[conn.topic] += 1
    return counts


def test_the_set_covers_empty_bags_services_and_both_storages():
    names = {b.name for b in BAGS}
    assert {"empty_bag", "only_services.mcap", "topics_and_services.db3", "talker_mcap", "talker_sqlite3"} <= names
    assert sum(_reference_counts(DATA / "empty_bag").values()) == 0


@pytest.mark.parametrize("bag", BAGS, ids=[b.name for b in BAGS])
def test_every_topic_is_listed_with_a_reason_and_import_says_why_nothing_was_written(bag, tmp_path, capsys):
    """None of these bags holds a type probeless converts: every topic is skipped with its reason, and
    `bag import` stops with one line (exit 2), never a traceback; service events in MCAP, whose
    definitions rosbags cannot parse, do not make the whole bag unreadable."""
    want = _reference_counts(bag)
    with RosBag(bag, preset="probeless") as rb:
        assert set(rb.skipped) == set(want) and not rb.roles
        for topic, why in rb.skipped.items():
            assert why.split(":")[0] in {c.msgtype for c in rb.reader.connections if c.topic == topic}
            if topic.endswith("/_service_event") and bag.suffix == ".mcap":
                assert "cannot parse its definition" in why or "no probeless message type" in why
    assert main(["bag", "import", str(bag), "-o", str(tmp_path / "out.mcap"), "--preset", "probeless",
                 "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holds no message" in err[0] and all(t in err[0] for t in want)
    assert not (tmp_path / "out.mcap").exists()


MCAPS = sorted(DATA.rglob("*.mcap"))


@pytest.mark.parametrize("path", MCAPS, ids=[p.parent.name + "/" + p.name for p in MCAPS])
def test_our_mcap_reader_counts_what_rosbag2_wrote(path):
    """`bag info`'s reader on rosbag2's MCAP files (CDR, ros2msg schemas): per-topic counts as rosbag2 recorded."""
    want = _reference_counts(path.parent if (path.parent / "metadata.yaml").exists() else path)
    with BagReader(path) as r:
        got = {t: info.count for t, info in r.topics().items()}
        assert all(info.message_encoding == "cdr" for info in r.topics().values())
    assert {t: n for t, n in got.items() if n} == {t: n for t, n in want.items() if n}
    assert set(got) <= set(want)
