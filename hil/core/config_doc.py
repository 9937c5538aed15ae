"""A config dataclass as the TOML a user would write: every key, its default and its meaning.

The meaning of each key is its field's entry in the class docstring's ``Attributes:``
section (Google style), so the printed file and the code's documentation are one text.
Nested dataclasses become tables (``[ros]``, ``[ros.topics]``); a field that is None by
default is printed commented out, with its type.
"""

from __future__ import annotations

import dataclasses
import math
import re
import textwrap
from typing import Any

__all__ = ["config_toml", "field_docs"]

_ENTRY = re.compile(r"^(\w+)(?: \([^)]*\))?:\s*(.*)$")


def field_docs(cls: type) -> dict[str, str]:
    """Return each field's description from `cls`'s docstring ``Attributes:`` section.

    Continuation lines (indented deeper than the entry) are joined with single spaces.
    """
    doc = textwrap.dedent("\n".join((cls.__doc__ or "").splitlines()[1:]))
    out: dict[str, str] = {}
    inside = False
    current: str | None = None
    for line in doc.splitlines():
        if line.strip() == "Attributes:":
            inside = True
            continue
        if not inside:
            continue
        if line and not line.startswith(" "):
            break  # the next section
        stripped = line.strip()
        entry = _ENTRY.match(stripped) if line.startswith("    ") and not line.startswith(
            "     ") else None
        if entry is not None:
            current = entry.group(1)
            out[current] = entry.group(2)
        elif current is not None and stripped:
            out[current] += " " + stripped
    return out


def config_toml(
    instance: Any,
    optional: dict[str, type] | None = None,
    skip: frozenset[str] = frozenset(),
) -> str:
    """Return `instance` (a dataclass) as commented TOML: every key with its value.

    Args:
        instance: The config with its defaults (or the values in force).
        optional: Tables absent by default (a field None): their class, printed commented
            out with its defaults where it has them.
        skip: Dotted keys not to print (e.g. a table that only the code fills in).
    """
    lines: list[str] = []
    _emit(instance, type(instance), "", lines, (optional or {}, skip), commented=False)
    return "\n".join(lines).strip() + "\n"


def _emit(instance: Any, cls: type, table: str, lines: list[str],
          options: tuple[dict[str, type], frozenset[str]], commented: bool) -> None:
    optional, skip = options
    docs = field_docs(cls)
    prefix = "# " if commented else ""
    nested: list[tuple[str, Any, type, bool]] = []
    if table:
        lines += ["", f"{prefix}[{table}]"]
    for f in dataclasses.fields(cls):
        value = getattr(instance, f.name) if instance is not None else _default(f)
        name = f"{table}.{f.name}" if table else f.name
        if name in skip:
            continue
        if dataclasses.is_dataclass(value):
            nested.append((name, value, type(value), commented))
            continue
        if value is None and f.name in optional:
            nested.append((name, None, optional[f.name], True))
            continue
        text = _literal(value)
        note = docs.get(f.name, "")
        entry = f"{prefix}{f.name} = {text}" if text else f"# {f.name} = (unset)"
        lines.append(f"{entry:<40} # {note}" if note else entry)
    for name, value, sub, sub_commented in nested:
        _emit(value, sub, name, lines, ({}, skip), sub_commented)


def _default(f: dataclasses.Field[Any]) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None


def _literal(value: Any) -> str:
    """Return `value` as a TOML literal; "" for None (a key left unset)."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, int):
        return str(value)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_literal(v) for v in value) + "]"
    return repr(value)
