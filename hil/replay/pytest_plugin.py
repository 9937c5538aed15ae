"""A pytest plugin that turns every recorded run in a directory into a test case.

``pytest --hil-logs DIR`` (repeatable) adds one test per log found in DIR (a
bag directory or a bare ``.mcap`` file), so a lab runs its own tank bags as a
regression suite beside the unit tests. Each test replays its log with
:func:`hil.replay.replayer.replay_log` and fails on a regression or when the log
cannot be replayed, printing the readable report; warnings
go to the test's report sections. Options:
``--hil-resim`` also re-simulates; ``--hil-tolerance K=V,...`` as ``hil replay``.

Registered as the ``pytest11`` entry point ``hil``; without the entry point,
load it with ``pytest -p hil.replay.pytest_plugin``.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from hil.replay.controllers import ScenarioCache
    from hil.replay.options import ReplayOptions
    from hil.replay.regression import LogReport


def pytest_addoption(parser: pytest.Parser) -> None:
    """Declare ``--hil-logs``, ``--hil-resim`` and ``--hil-tolerance``."""
    group = parser.getgroup("hil", "replay of recorded hil runs")
    group.addoption(
        "--hil-logs",
        action="append",
        default=[],
        metavar="DIR",
        help="replay every log in DIR as a test case (repeatable)",
    )
    group.addoption(
        "--hil-resim",
        action="store_true",
        default=False,
        help="also re-simulate each recorded run (closed loop)",
    )
    group.addoption(
        "--hil-tolerance",
        default="",
        metavar="K=V,...",
        help="thresholds, as `hil replay --tolerance`",
    )


def find_logs(directory: Path) -> list[Path]:
    """Return the logs directly inside `directory`: bag directories and ``.mcap`` files.

    Hidden entries are ignored. A path that is itself a bag is returned alone.
    """
    if (directory / "metadata.yaml").is_file() or directory.suffix == ".mcap":
        return [directory]
    if not directory.is_dir():
        return [directory]  # reported as a failing test that names the missing path
    out = []
    for entry in sorted(directory.iterdir()):
        if entry.name.startswith("."):
            continue
        is_bag = entry.is_dir() and (
            (entry / "metadata.yaml").is_file() or any(entry.glob("*.mcap"))
        )
        if is_bag or (entry.is_file() and entry.suffix == ".mcap"):
            out.append(entry)
    return out


class HilReplayError(Exception):
    """A replayed log regressed or could not be replayed; carries the readable report."""


class HilLogItem(pytest.Item):
    """One recorded log replayed as a test."""

    def __init__(self, *, log_path: Path, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.log_path = log_path

    def _options(self) -> ReplayOptions:
        from hil.replay.options import ReplayOptions, Tolerance

        tolerance = Tolerance.parse(str(self.config.getoption("hil_tolerance")))
        return ReplayOptions(tolerance=tolerance, resim=bool(self.config.getoption("hil_resim")))

    def _caches(self) -> ScenarioCache:
        from hil.replay.controllers import ScenarioCache

        stash_key = _CACHE_KEY
        if stash_key not in self.config.stash:
            self.config.stash[stash_key] = ScenarioCache()
        cache: ScenarioCache = self.config.stash[stash_key]
        return cache

    def runtest(self) -> None:
        """Replay the log; raise HilReplayError on a regression or a bad log."""
        from hil.replay.regression import Status, render
        from hil.replay.replayer import replay_log

        report: LogReport = replay_log(self.log_path, self._options(), self._caches())
        text = render(report, max_findings=10)
        self.add_report_section("call", "hil replay", text)
        if report.status in (Status.FAIL, Status.ERROR):
            raise HilReplayError(text)
        if report.checks and all(c.status is Status.SKIP for c in report.checks):
            pytest.skip(f"nothing to check in {self.log_path}: {report.checks[0].summary}")

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException], style: Any = None) -> str:
        """Show the readable report instead of a traceback."""
        if isinstance(excinfo.value, HilReplayError):
            return str(excinfo.value)
        return str(super().repr_failure(excinfo, style=style))

    def reportinfo(self) -> tuple[Path, int | None, str]:
        """Name the log in pytest's summary."""
        return self.log_path, None, f"hil replay {self.log_path}"


_CACHE_KEY = pytest.StashKey["ScenarioCache"]()


class HilLogDirectory(pytest.Collector):
    """The logs of one ``--hil-logs`` directory."""

    def __init__(self, *, log_dir: Path, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.log_dir = log_dir

    def collect(self) -> Iterator[HilLogItem]:
        """Yield one item per log."""
        for log in find_logs(self.log_dir):
            yield HilLogItem.from_parent(self, name=log.name, log_path=log)


def pytest_collection_modifyitems(
    session: pytest.Session, config: pytest.Config, items: list[pytest.Item]
) -> None:
    """Append one test per log of every ``--hil-logs`` directory."""
    for raw in config.getoption("hil_logs"):
        directory = Path(raw)
        collector = HilLogDirectory.from_parent(
            session, name=f"hil-logs:{directory}", log_dir=directory
        )
        items.extend(collector.collect())
