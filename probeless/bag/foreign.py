"""Channels of other writers in ``bag export``: copied as they are where Foxglove decodes them.

Foxglove reads json, protobuf, ros1, cdr (ROS 2) and flatbuffer channels with their schemas
itself, so these are copied byte for byte, schema included. Any other encoding is counted per
topic and named ``not decodable: <encoding>``. ``summary`` is an
:class:`~probeless.bag.export.ExportSummary` (``written``, ``skipped``, ``schemas`` per topic).
"""

from __future__ import annotations

from typing import Any

from mcap.records import Channel, Message

# (message encoding, schema encoding) of other writers' channels that Foxglove decodes itself: copied as they are
PASSTHROUGH = {("json", ""), ("json", "jsonschema"), ("protobuf", "protobuf"), ("ros1", "ros1msg"),
               ("cdr", "ros2msg"), ("cdr", "ros2idl"), ("cdr", "omgidl"), ("flatbuffer", "flatbuffer")}


def not_decodable(ch: Channel, summary: Any) -> None:
    """Count a message of ``ch`` as skipped and name the channel's encoding as not decodable."""
    summary.skipped[ch.topic] = summary.skipped.get(ch.topic, 0) + 1
    summary.schemas.setdefault(ch.topic, f"not decodable: {ch.message_encoding or '(no encoding)'}")


class Passthrough:
    """Copies messages of the foreign encodings Foxglove decodes, with their schemas, byte for byte."""

    def __init__(self, writer: Any):
        self.writer = writer
        self.schemas: dict[tuple, int] = {}
        self.channels: dict[tuple, int] = {}

    def add(self, r: Any, ch: Channel, m: Message, summary: Any) -> None:
        """Write ``m`` of ``ch`` read by BagReader ``r`` (or count it as not decodable) into ``summary``."""
        schema = r.schema_of(ch)
        enc = schema.encoding if schema is not None else ""
        if (ch.message_encoding, enc) not in PASSTHROUGH:
            not_decodable(ch, summary)
            return
        key = (ch.topic, ch.message_encoding, enc)
        if key not in self.channels:
            sid = 0
            if schema is not None:
                skey = (schema.name, enc, bytes(schema.data))
                if skey not in self.schemas:
                    self.schemas[skey] = self.writer.register_schema(name=schema.name, encoding=enc, data=skey[2])
                sid = self.schemas[skey]
            self.channels[key] = self.writer.register_channel(ch.topic, ch.message_encoding, sid, dict(ch.metadata))
            name = schema.name if schema is not None else "-"
            summary.schemas[ch.topic] = f"passed through ({ch.message_encoding}, schema {name})"
        self.writer.add_message(self.channels[key], log_time=m.log_time, publish_time=m.publish_time,
                                sequence=m.sequence, data=bytes(m.data))
        summary.written[ch.topic] = summary.written.get(ch.topic, 0) + 1
