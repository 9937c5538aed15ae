"""Frozen dataclasses to JSON-ready values and back, exactly, driven by their type hints.

A campaign streams each finished run to a results file and a resumed campaign reads
it back; the runs it reads must equal the runs it would have computed. So the
encoding keeps what plain ``json.dumps(asdict(x))`` loses: tuples come back as
tuples, enums as enums, paths as paths, nested dataclasses as themselves, floats
bit for bit (``repr`` round trips; NaN and infinities as Python's ``json`` writes
them, ``NaN`` and ``Infinity``).

Supported annotations: bool, int, float, str, None, Path, Enum subclasses,
dataclasses, ``tuple[X, ...]``, ``tuple[X, Y]``, ``list[X]``, ``dict[str, X]``,
unions (``X | None``) and ``Any`` (kept as it is, tuples as lists).
"""

from __future__ import annotations

import dataclasses
import enum
import typing
from functools import cache
from pathlib import Path
from typing import Any, TypeVar, overload

from hil.core.unions import first_member, is_union

__all__ = ["CodecError", "from_jsonable", "to_jsonable"]

T = TypeVar("T")


class CodecError(ValueError):
    """A value does not match the type it should decode to."""


def to_jsonable(value: object) -> Any:
    """Return `value` as dicts, lists, strings, numbers, booleans and None.

    Dataclasses become dicts of their fields, enums their value, paths strings,
    tuples lists; numpy scalars become Python numbers.
    """
    if value is None or isinstance(value, bool | int | float | str):
        return value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: to_jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, enum.Enum):
        return to_jsonable(value.value)
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, list | tuple):
        return [to_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    item = getattr(value, "item", None)  # a numpy scalar
    if callable(item):
        return to_jsonable(item())
    raise CodecError(f"cannot encode {type(value).__name__} value {value!r}")


@cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


@overload
def from_jsonable(kind: type[T], data: Any) -> T: ...


@overload
def from_jsonable(kind: Any, data: Any) -> Any: ...


def from_jsonable(kind: Any, data: Any) -> Any:
    """Rebuild a value of type `kind` from :func:`to_jsonable`'s form.

    Raises:
        CodecError: `data` does not fit `kind` (naming both).
    """
    return _decode(kind, data)


def _decode(kind: Any, data: Any) -> Any:
    if kind is Any:
        return data
    origin = typing.get_origin(kind)
    if is_union(kind):
        found = first_member(kind, data, lambda option: _decode(option, data), CodecError)
        if found.ok:
            return found.value
        raise CodecError(f"{data!r} fits none of {kind!r}: {'; '.join(found.errors)}")
    if origin is tuple:
        args = typing.get_args(kind)
        _expect(isinstance(data, list), kind, data)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_decode(args[0], v) for v in data)
        _expect(len(args) == len(data), kind, data)
        return tuple(_decode(a, v) for a, v in zip(args, data, strict=True))
    if origin is list:
        _expect(isinstance(data, list), kind, data)
        (arg,) = typing.get_args(kind)
        return [_decode(arg, v) for v in data]
    if origin is dict:
        _expect(isinstance(data, dict), kind, data)
        _, arg = typing.get_args(kind)
        return {k: _decode(arg, v) for k, v in data.items()}
    if kind is type(None):
        _expect(data is None, kind, data)
        return None
    if isinstance(kind, type) and dataclasses.is_dataclass(kind):
        _expect(isinstance(data, dict), kind, data)
        hints = _hints(kind)
        known = {f.name for f in dataclasses.fields(kind) if f.init}
        unknown = set(data) - known
        _expect(not unknown, kind, data, f"unknown fields {sorted(unknown)!r}")
        try:
            return kind(**{name: _decode(hints[name], v) for name, v in data.items()})
        except TypeError as err:  # a required field missing
            raise CodecError(f"cannot build {kind.__name__} from {data!r}: {err}") from err
    if isinstance(kind, type) and issubclass(kind, enum.Enum):
        try:
            return kind(data)
        except ValueError as err:
            raise CodecError(f"{data!r} is no {kind.__name__}") from err
    if kind is Path:
        _expect(isinstance(data, str), kind, data)
        return Path(data)
    if kind is float:
        _expect(isinstance(data, int | float) and not isinstance(data, bool), kind, data)
        return float(data)
    if kind is int or kind is str or kind is bool:
        _expect(type(data) is kind, kind, data)
        return data
    raise CodecError(f"cannot decode values of type {kind!r}")


def _expect(ok: bool, kind: Any, data: Any, why: str = "") -> None:
    if not ok:
        name = getattr(kind, "__name__", repr(kind))
        raise CodecError(f"{data!r} is no {name}" + (f" ({why})" if why else ""))
