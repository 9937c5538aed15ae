#!/usr/bin/env python3
"""List the functions longer than a limit, counted from the def line to the last line.

Usage:

    python3 tools/long_functions.py [--max N] [PATH ...]   # default: --max 80 hil

Prints `path:line name length` for each function (methods and nested functions too)
over the limit, longest first, and exits 1 if any is not in EXEMPT; 0 otherwise.
Decorator lines are not counted (the def line starts the count), blank lines and
comments inside the body are.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

MAX_LINES = 80

# (path relative to the repository root, function name): functions allowed over the limit,
# each with its reason. None today: the solver's two hot kernels, box_test and
# _apply_heading, are split into steps that numba inlines (hil.core.jit.njit_inline), as
# fast as the whole kernels were.
EXEMPT: frozenset[tuple[str, str]] = frozenset()

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class LongFunction:
    """One function over the limit.

    Attributes:
        path: the file, relative to the repository root (POSIX separators).
        line: the def line (1-based).
        name: the function's name (unqualified).
        length: lines from the def line to the last line of the body, both included.
    """

    path: str
    line: int
    name: str
    length: int

    @property
    def exempt(self) -> bool:
        """Whether this function is one of EXEMPT."""
        return (self.path, self.name) in EXEMPT


def _python_files(paths: list[Path]) -> Iterator[Path]:
    for path in paths:
        if path.is_dir():
            yield from sorted(path.rglob("*.py"))
        else:
            yield path


def _relative(path: Path) -> str:
    resolved = path.resolve()
    return resolved.relative_to(ROOT).as_posix() if resolved.is_relative_to(ROOT) else str(path)


def long_functions(paths: list[Path], max_lines: int = MAX_LINES) -> list[LongFunction]:
    """Find every function in the Python files under `paths` longer than `max_lines`.

    Args:
        paths: files or folders (folders are searched for `*.py` recursively).
        max_lines: the longest a function may be, def line to last line.

    Returns:
        The functions over the limit, longest first.
    """
    found = []
    for file in _python_files(paths):
        tree = ast.parse(file.read_text(), filename=str(file))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > max_lines:
                    found.append(LongFunction(_relative(file), node.lineno, node.name, length))
    return sorted(found, key=lambda f: (-f.length, f.path, f.line))


def main(argv: list[str]) -> int:
    """List the long functions; return 1 if any is not exempt."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max", type=int, default=MAX_LINES, help="longest allowed, in lines")
    parser.add_argument("paths", nargs="*", type=Path, default=[ROOT / "hil"])
    args = parser.parse_args(argv)
    found = long_functions(args.paths, args.max)
    for f in found:
        print(f"{f.path}:{f.line} {f.name} {f.length}{' (exempt)' if f.exempt else ''}")
    return 1 if any(not f.exempt for f in found) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
