"""Values of a union type hint (``X | Y | None``): the one rule for trying its members.

Both readers of typed values, the JSON codec (:mod:`hil.core.codec`) and the config
loader (:mod:`hil.core.config`), take a union the same way: None where the union admits
None, else the value as the first member that accepts it.
"""

from __future__ import annotations

import types
import typing
from collections.abc import Callable
from typing import Any, NamedTuple


class UnionResult(NamedTuple):
    """What :func:`first_member` found."""

    ok: bool
    """A member (or None) took the value."""
    value: Any
    """The converted value (None when not `ok`)."""
    errors: list[str]
    """Why each member refused it, in the union's order (empty when `ok`)."""


def is_union(hint: Any) -> bool:
    """Return whether `hint` is a union (``typing.Union`` or ``X | Y``)."""
    return typing.get_origin(hint) in (typing.Union, types.UnionType)


def first_member(
    hint: Any, value: Any, convert: Callable[[Any], Any], error: type[Exception]
) -> UnionResult:
    """Convert `value` to the first member of the union `hint` that takes it.

    Args:
        hint: A union type hint.
        value: The value read (None takes the union's None, if it has one).
        convert: Member hint -> the value converted to it; raises `error` if it cannot.
        error: The exception by which `convert` refuses.
    """
    options = typing.get_args(hint)
    if value is None and type(None) in options:
        return UnionResult(True, None, [])
    errors = []
    for option in options:
        if option is type(None):
            continue
        try:
            return UnionResult(True, convert(option), [])
        except error as err:
            errors.append(str(err))
    return UnionResult(False, None, errors)
