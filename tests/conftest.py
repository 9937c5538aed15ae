"""Make the suite independent of where pytest found (or did not find) its settings.

``pytest --hil-logs /other/dir`` makes pytest look for its configuration from
/other/dir (it takes option values for paths when choosing the root), so
pyproject.toml's ``pythonpath``, markers and warning filters are not read. The
repository root goes on ``sys.path`` here, so ``tests.<folder>.<module>`` imports
anyway, and the settings pytest missed are applied from pyproject.toml.
"""

from __future__ import annotations

import sys
import tomllib
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
