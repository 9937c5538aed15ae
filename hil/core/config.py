"""Read TOML tables with errors that name the key: the one home of key and type checks.

Configuration files map onto the dataclasses that hold the settings: each
field is a key, nested dataclasses are sub-tables, and a wrong, missing or
unknown key is refused with its path and the expected type (:func:`from_table`).
Files whose layout is not one dataclass per table (scenarios) read their keys
with the same checks, one key at a time (:func:`table`, :func:`check_keys`,
:func:`number`, :func:`numbers`), so every file names a bad key the same way:
``key grid.'cell_m' must be ...``, the table's path, then the key quoted.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import typing
from pathlib import Path
from typing import Any, TypeVar

from hil.core.unions import first_member, is_union

__all__ = [
    "ConfigError",
    "check_keys",
    "from_table",
    "key_name",
    "load_toml",
    "number",
    "numbers",
    "table",
]

T = TypeVar("T")


class ConfigError(ValueError):
    """A configuration file or table that cannot be used; the message names the key."""


def load_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file.

    Raises:
        ConfigError: The file is missing or not valid TOML.
    """
    p = Path(path)
    try:
        with p.open("rb") as f:
            return tomllib.load(f)
    except FileNotFoundError as err:
        raise ConfigError(f"config file {str(p)!r} does not exist") from err
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"config file {str(p)!r} is not valid TOML: {err}") from err


def key_name(where: str, key: str) -> str:
    """Return how messages name `key` in the table at `where` (``grid.'cell_m'``).

    Args:
        where: Path of the table with a trailing dot (``"grid."``), ``""`` at the top.
        key: The key.
    """
    return f"{where}{key!r}"


def table(
    data: dict[str, Any], key: str, where: str = "", *, required: bool = True
) -> dict[str, Any]:
    """Return the sub-table `key` of `data` (an empty one if absent and not required).

    Raises:
        ConfigError: The key is missing (and required) or not a table.
    """
    if key not in data:
        if required:
            raise ConfigError(f"missing key {key_name(where, key)}")
        return {}
    value = data[key]
    if not isinstance(value, dict):
        raise ConfigError(f"key {key_name(where, key)} must be a table, got {value!r}")
    return value


def check_keys(data: dict[str, Any], allowed: set[str], where: str = "", note: str = "") -> None:
    """Refuse a key of `data` that is not in `allowed`.

    Args:
        data: The table.
        allowed: The keys it may hold.
        where: Path of the table with a trailing dot.
        note: A hint appended to the message (e.g. that keys carry their unit).

    Raises:
        ConfigError: Naming the first unknown key (sorted) and the allowed ones.
    """
    unknown = sorted(set(data) - allowed)
    if unknown:
        hint = f"; {note}" if note else ""
        raise ConfigError(
            f"unknown key {key_name(where, unknown[0])} "
            f"(allowed: {', '.join(sorted(allowed))}){hint}"
        )


def _finite(value: Any, where: str, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ConfigError(f"key {key_name(where, key)} must be a finite number, got {value!r}")
    return float(value)


def _finite_list(value: Any, where: str, key: str, n: int) -> tuple[float, ...]:
    if (
        not isinstance(value, list)
        or len(value) != n
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
        or not all(math.isfinite(v) for v in value)
    ):
        raise ConfigError(
            f"key {key_name(where, key)} must be a list of {n} finite numbers, got {value!r}"
        )
    return tuple(float(v) for v in value)


def number(data: dict[str, Any], key: str, where: str = "", default: float | None = None) -> float:
    """Return `data[key]` as a finite float, or `default` when absent.

    Raises:
        ConfigError: The key is missing without a default, or not a finite number.
    """
    if key not in data:
        if default is None:
            raise ConfigError(f"missing key {key_name(where, key)}")
        return default
    return _finite(data[key], where, key)


def numbers(data: dict[str, Any], key: str, where: str, n: int) -> tuple[float, ...]:
    """Return `data[key]`, a list of `n` finite numbers, as a tuple of floats.

    Raises:
        ConfigError: The key is missing or not a list of `n` finite numbers.
    """
    if key not in data:
        raise ConfigError(f"missing key {key_name(where, key)}")
    return _finite_list(data[key], where, key, n)


def _convert(value: Any, hint: Any, where: str, key: str, note: str) -> Any:
    origin = typing.get_origin(hint)
    name = key_name(where, key)
    if is_union(hint):
        found = first_member(
            hint, value, lambda option: _convert(value, option, where, key, note), ConfigError
        )
        if found.ok:
            return found.value
        raise ConfigError(found.errors[0] if found.errors else f"key {name} has an unusable value")
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        if not isinstance(value, dict):
            raise ConfigError(f"key {name} must be a table, got {value!r}")
        return from_table(hint, value, f"{where}{key}.", note=note)
    if origin is tuple:
        args = typing.get_args(hint)
        if not isinstance(value, list):
            raise ConfigError(f"key {name} must be a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(
                _convert(v, args[0], where, f"{key}[{i}]", note) for i, v in enumerate(value)
            )
        if all(a is float for a in args):
            return _finite_list(value, where, key, len(args))
        if len(value) != len(args):
            raise ConfigError(f"key {name} must have {len(args)} entries, got {value!r}")
        return tuple(
            _convert(v, a, where, f"{key}[{i}]", note)
            for i, (v, a) in enumerate(zip(value, args, strict=True))
        )
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"key {name} must be true or false, got {value!r}")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"key {name} must be an integer, got {value!r}")
        return value
    if hint is float:
        return _finite(value, where, key)
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(f"key {name} must be a string, got {value!r}")
        return value
    raise ConfigError(f"key {name}: unsupported setting type {hint!r}")


def from_table(cls: type[T], data: dict[str, Any], where: str = "", *, note: str = "") -> T:
    """Build dataclass `cls` from a TOML table; absent keys keep their defaults.

    Args:
        cls: A dataclass type whose fields are numbers, strings, booleans, tuples,
            optionals or nested dataclasses.
        data: The table.
        where: Path of the table with a trailing dot (``"ros."``), for messages.
        note: A hint appended to an unknown-key message (see :func:`check_keys`).

    Raises:
        ConfigError: Unknown, missing or mistyped keys, or a value the dataclass refuses.
    """
    assert dataclasses.is_dataclass(cls)
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    check_keys(data, set(fields), where, note)
    kwargs = {}
    for name, field in fields.items():
        if name in data:
            kwargs[name] = _convert(data[name], hints[name], where, name, note)
        elif field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING:
            raise ConfigError(f"missing key {key_name(where, name)}")
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as err:
        raise ConfigError(f"table {where.rstrip('.') or 'top level'!r}: {err}") from err
