"""JSON Schema (draft 2020-12) of a message type's wire document, stored as the MCAP schema.

The document described is the msgpack metadata frame of :mod:`probeless.wire`: the envelope
``{type, version, publisher, publish_ns, fields}`` where ``fields`` holds the message's fields.
Array fields appear as ``[buffer index, dtype, shape]``; the array itself travels as its own frame.
Tools that do not know probeless can read the structure of a recording from it; probeless itself
decodes with the registered classes and checks the version in the envelope.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from probeless.errors import BagError
from probeless.messages.base import ArraySpec, FieldSpec, Message, registry, schema_of

DRAFT = "https://json-schema.org/draft/2020-12/schema"
_SCALARS = {"int": "integer", "float": "number", "str": "string", "bool": "boolean"}


def json_schema(cls: type[Message]) -> dict[str, Any]:
    """JSON Schema of the wire document of message class ``cls`` (a registered Message)."""
    doc = (cls.__doc__ or "").strip().splitlines()
    return {
        "$schema": DRAFT,
        "title": cls.TYPE_NAME,
        "description": doc[0] if doc else cls.TYPE_NAME,
        "x-probeless-version": cls.VERSION,
        "type": "object",
        "properties": {
            "type": {"const": cls.TYPE_NAME},
            "version": {"const": cls.VERSION},
            "publisher": {"type": "string", "description": "id of the publishing node"},
            "publish_ns": {"type": "integer", "description": "wall-clock publish time [ns since the Unix epoch]"},
            "fields": _struct_schema(cls),
        },
        "required": ["type", "version", "publisher", "publish_ns", "fields"],
        "additionalProperties": False,
    }


def _struct_schema(cls: type) -> dict[str, Any]:
    specs = schema_of(cls)
    return {
        "title": cls.__name__,
        "type": "object",
        "properties": {s.name: _field_schema(s) for s in specs},
        "required": [s.name for s in specs],
        "additionalProperties": False,
    }


def _field_schema(spec: FieldSpec) -> dict[str, Any]:
    if spec.kind in _SCALARS:
        return {"type": _SCALARS[spec.kind]}
    if spec.kind == "struct":
        return _struct_schema(spec.struct)
    if spec.kind == "tuple":
        return {"type": "array", "items": _field_schema(spec.item)}
    return _array_schema(spec.array)


def _array_schema(spec: ArraySpec) -> dict[str, Any]:
    dims = [{"const": d} if isinstance(d, int) else {"type": "integer", "minimum": 0} for d in spec.shape]
    return {
        "type": "array",
        "description": f"array sent as its own frame: [buffer index, dtype, shape], {spec.describe()}",
        "prefixItems": [
            {"type": "integer", "minimum": 0, "description": "index of the array frame after the metadata"},
            {"enum": sorted({np.dtype(d).str for d in spec.dtypes}),
             "description": "numpy dtype.str"},
            {"type": "array", "prefixItems": dims, "items": False,
             "minItems": len(spec.shape), "maxItems": len(spec.shape),
             "x-shape": ["*" if d is None else d for d in spec.shape]},
        ],
        "items": False,
        "minItems": 3,
        "maxItems": 3,
    }


def check_schemas(bag: str, recorded: dict[str, tuple[str, int]]) -> None:
    """Every recorded topic's type must be known to this build, with the same schema version."""
    known = registry()
    for topic, (type_name, version) in sorted(recorded.items()):
        if type_name not in known:
            raise BagError(f"{bag}: topic {topic!r} has message type {type_name!r}, unknown to this build")
        if version != known[type_name].VERSION:
            raise BagError(f"{bag}: topic {topic!r} was recorded with {type_name} schema version {version}, "
                           f"this build has version {known[type_name].VERSION}")
