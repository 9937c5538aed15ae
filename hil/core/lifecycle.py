"""Objects opened by ``with``: the one ``__enter__``/``__exit__`` pair of open/close types."""

from __future__ import annotations

from typing import Self


class OpenedByWith:
    """Base of a type with ``open()`` and ``close()``: ``with x:`` opens it, and closes it.

    ``__enter__`` calls :meth:`open` and returns the object; ``__exit__`` calls
    :meth:`close` whatever happened in the block (an exception goes on after it).
    """

    def open(self) -> None:
        """Acquire what the object needs (the subclass's)."""
        raise NotImplementedError

    def close(self) -> None:
        """Release it (the subclass's)."""
        raise NotImplementedError

    def __enter__(self) -> Self:
        """Open, and return the object."""
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        """Close (`exc`: the block's exception, if any, which goes on)."""
        self.close()
