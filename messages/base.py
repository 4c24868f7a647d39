"""Typed message machinery: frozen dataclasses with numpy fields, checked on construction.

A message family module declares classes like::

    @message("sensor/Image", version=1)
    @dataclass(frozen=True)
    class Image(Message):
        header: Header
        data: np.ndarray = array(("uint8", "uint16", "float32"), ("h", "w", "c"))  # pixels, row-major

Supported field types: ``int``, ``float``, ``str``, ``bool``, ``np.ndarray`` (declared with
:func:`array`), a nested :class:`Struct`, and ``tuple[X, ...]`` of any of the scalars or a Struct.
Arrays are made C-contiguous on construction (never rejected for layout); a wrong dtype, rank or
fixed dimension raises :class:`SchemaError`. Named dimensions (``"h"``) must agree across the
arrays of one message.
"""

from __future__ import annotations

import dataclasses
import typing
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from probeless.errors import SchemaError

# Dtypes allowed anywhere on the wire: plain numeric, little-endian or byte-sized. No objects.
WIRE_DTYPES = frozenset(np.dtype(d).str for d in (
    "bool", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
    "float16", "float32", "float64", "complex64", "complex128"))

_SCALARS = {int: "int", float: "float", str: "str", bool: "bool"}


@dataclass(frozen=True)
class ArraySpec:
    """Declared dtype set and shape of an array field. Shape entries: int (fixed), str (named), None (any)."""

    dtypes: tuple[str, ...]
    shape: tuple[int | str | None, ...]

    @property
    def dtype_set(self) -> frozenset:
        """The allowed dtypes as numpy dtype objects (cached), for fast membership tests."""
        cached = self.__dict__.get("_dtype_set")
        if cached is None:
            cached = frozenset(np.dtype(d) for d in self.dtypes)
            object.__setattr__(self, "_dtype_set", cached)
        return cached

    def describe(self) -> str:
        dims = ", ".join("*" if d is None else str(d) for d in self.shape)
        return f"{'|'.join(self.dtypes)}[{dims}]"


@dataclass(frozen=True)
class FieldSpec:
    """One field of a struct, resolved from its annotation: kind is int|float|str|bool|array|struct|tuple."""

    name: str
    kind: str
    array: ArraySpec | None = None
    struct: type | None = None
    item: "FieldSpec | None" = None  # element spec of a tuple field


def array(dtypes: str | tuple[str, ...], shape: tuple[int | str | None, ...], *,
          default_factory: typing.Callable[[], np.ndarray] | None = None) -> typing.Any:
    """Declare an ndarray field with its allowed dtypes and shape (see :class:`ArraySpec`).

    ``default_factory`` (optional) makes the field optional; it must return a fresh array.
    """
    names = (dtypes,) if isinstance(dtypes, str) else tuple(dtypes)
    spec = ArraySpec(tuple(np.dtype(d).name for d in names), tuple(shape))
    if default_factory is None:
        return dataclasses.field(metadata={"array": spec})
    return dataclasses.field(default_factory=default_factory, metadata={"array": spec})


class Struct:
    """Base of every wire struct: validates and normalises fields after ``__init__``.

    Subclasses add semantic checks (an encoding matching the dtype, a rigid transform, ...) by
    overriding :meth:`validate`; it runs after the field checks, and again on every decode.
    """

    def __post_init__(self) -> None:
        dims: dict[str, int] = {}
        for spec in schema_of(type(self)):
            value = getattr(self, spec.name)
            fixed = _check(spec, value, f"{type(self).__name__}.{spec.name}", dims)
            if fixed is not value:
                object.__setattr__(self, spec.name, fixed)
        self.validate()

    def validate(self) -> None:
        """Semantic checks beyond field types; raise SchemaError naming ``Class.field``."""


class Message(Struct):
    """A top-level message: registered under a stable type name, carries ``header``."""

    TYPE_NAME: typing.ClassVar[str] = ""
    VERSION: typing.ClassVar[int] = 0


_REGISTRY: dict[str, type[Message]] = {}


def message(type_name: str, version: int = 1):
    """Class decorator registering a frozen Message dataclass under ``type_name``."""

    def register(cls: type[Message]) -> type[Message]:
        if not (dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen):
            raise TypeError(f"{cls.__name__} must be a frozen dataclass")
        if not issubclass(cls, Message):
            raise TypeError(f"{cls.__name__} must derive from Message")
        if type_name in _REGISTRY and _REGISTRY[type_name] is not cls:
            raise TypeError(f"message type name {type_name!r} registered twice")
        if "header" not in {f.name for f in dataclasses.fields(cls)}:
            raise TypeError(f"{cls.__name__} has no header field")
        cls.TYPE_NAME, cls.VERSION = type_name, version
        _REGISTRY[type_name] = cls
        schema_of(cls)  # resolve annotations now, so mistakes fail at import
        return cls

    return register


def registry() -> dict[str, type[Message]]:
    """All registered message types by type name (imports every family first)."""
    import probeless.messages  # noqa: F401  (registers the families)
    return dict(_REGISTRY)


def lookup(type_name: str) -> type[Message]:
    """The message class for ``type_name``; raises SchemaError when unknown."""
    cls = _REGISTRY.get(type_name)
    if cls is None:
        cls = registry().get(type_name)
        if cls is None:
            raise SchemaError(f"unknown message type {type_name!r}")
    return cls


@lru_cache(maxsize=None)
def schema_of(cls: type) -> tuple[FieldSpec, ...]:
    """The resolved field specs of a Struct dataclass, in declaration order."""
    hints = typing.get_type_hints(cls)
    return tuple(_spec(f.name, hints[f.name], f.metadata) for f in dataclasses.fields(cls))


def _spec(name: str, hint: typing.Any, metadata: typing.Mapping) -> FieldSpec:
    if hint is np.ndarray:
        if "array" not in metadata:
            raise TypeError(f"array field {name!r} must be declared with array(dtypes, shape)")
        return FieldSpec(name, "array", array=metadata["array"])
    if hint in _SCALARS:
        return FieldSpec(name, _SCALARS[hint])
    if isinstance(hint, type) and issubclass(hint, Struct):
        return FieldSpec(name, "struct", struct=hint)
    if typing.get_origin(hint) is tuple:
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return FieldSpec(name, "tuple", item=_spec(name, args[0], {}))
    raise TypeError(f"unsupported field type for {name!r}: {hint!r}")


def _check(spec: FieldSpec, value: typing.Any, where: str, dims: dict[str, int]) -> typing.Any:
    """Validate one value against its spec; return it, possibly normalised."""
    kind = spec.kind
    if kind == "array":
        return _check_array(spec.array, value, where, dims)
    if kind == "bool":
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
    elif kind == "int":
        if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
            return int(value)
    elif kind == "float":
        if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
            return float(value)
    elif kind == "str":
        if isinstance(value, str):
            return value
    elif kind == "struct":
        if isinstance(value, spec.struct):
            return value
    elif kind == "tuple":
        if isinstance(value, (tuple, list)):
            return tuple(_check(spec.item, v, f"{where}[{i}]", {}) for i, v in enumerate(value))
    raise SchemaError(f"{where}: expected {describe(spec)}, got {type(value).__name__}")


def _check_array(spec: ArraySpec, value: typing.Any, where: str, dims: dict[str, int]) -> np.ndarray:
    if not isinstance(value, np.ndarray):
        raise SchemaError(f"{where}: expected ndarray {spec.describe()}, got {type(value).__name__}")
    if value.dtype not in spec.dtype_set and value.dtype.newbyteorder("=") not in spec.dtype_set:
        raise SchemaError(f"{where}: dtype {value.dtype.name} not in {spec.describe()}")
    if value.ndim != len(spec.shape):
        raise SchemaError(f"{where}: shape {value.shape} has rank {value.ndim}, expected {spec.describe()}")
    for size, want in zip(value.shape, spec.shape):
        if isinstance(want, int) and size != want:
            raise SchemaError(f"{where}: shape {value.shape} does not match {spec.describe()}")
        if isinstance(want, str):
            if dims.setdefault(want, size) != size:
                raise SchemaError(f"{where}: dimension {want!r} is {size}, elsewhere {dims[want]}")
    if not value.flags.c_contiguous or value.dtype.byteorder == ">":
        value = np.ascontiguousarray(value, dtype=value.dtype.newbyteorder("="))
    return value


def describe(spec: FieldSpec) -> str:
    """Human-readable type of a field, as used in error messages and schema dumps."""
    if spec.kind == "array":
        return f"ndarray {spec.array.describe()}"
    if spec.kind == "struct":
        return spec.struct.__name__
    if spec.kind == "tuple":
        return f"tuple[{describe(spec.item)}, ...]"
    return spec.kind


def messages_equal(a: typing.Any, b: typing.Any) -> bool:
    """Deep equality of two structs/messages: same type, equal scalars, arrays equal in dtype, shape, values."""
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))
    if isinstance(a, Struct):
        return all(messages_equal(getattr(a, s.name), getattr(b, s.name)) for s in schema_of(type(a)))
    if isinstance(a, tuple):
        return len(a) == len(b) and all(messages_equal(x, y) for x, y in zip(a, b))
    return a == b
