"""Make the suite independent of where pytest found (or did not find) its settings.

``pytest --hil-logs /other/dir`` makes pytest look for its configuration from
/other/dir (it takes option values for paths when choosing the root), so
pyproject.toml's ``pythonpath``, markers and warning filters are not read. The
repository root goes on ``sys.path`` here, so ``tests.<folder>.<module>`` imports
anyway, and the settings pytest missed are applied from pyproject.toml.
"""

from __future__ import annotations

import signal
import sys
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def pytest_configure(config: pytest.Config) -> None:
    """Register pyproject.toml's markers and warning filters when pytest missed the file."""
    if config.inipath is not None:
        return
    with (ROOT / "pyproject.toml").open("rb") as f:
        ini = tomllib.load(f)["tool"]["pytest"]["ini_options"]
    for name in ("markers", "filterwarnings"):
        for line in ini.get(name, []):
            config.addinivalue_line(name, line)


@pytest.fixture(autouse=True)
def _sigint_left_as_found() -> Iterator[None]:
    """Fail a test that leaves Ctrl-C handled otherwise than it found it (then restore it).

    Tests share their process with the tests after them (an xdist worker): a handler left
    behind would change what a later test's SIGINT does (the Ctrl-C tests).
    """
    before = signal.getsignal(signal.SIGINT)
    yield
    after = signal.getsignal(signal.SIGINT)
    if after is not before:
        signal.signal(signal.SIGINT, before)
        pytest.fail(f"the test left SIGINT handled by {after!r} (found {before!r})")
