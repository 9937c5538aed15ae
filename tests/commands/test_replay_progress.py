"""Progress of a replay: shown on a terminal only, never in the way of the reports."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.commands.replay_progress import ReplayProgress


def test_progress_is_off_when_stderr_is_no_terminal(capsys: pytest.CaptureFixture[str]) -> None:
    with ReplayProgress(3) as progress:
        assert not progress.enabled
        progress.step(Path("logs/a"))("stack")
        progress.done()
    assert capsys.readouterr() == ("", "")


def test_progress_shows_the_log_and_its_step() -> None:
    with ReplayProgress(2, enabled=True) as progress:
        progress.step(Path("logs/run-a"))("decisions")
        task = progress._progress.tasks[0] if progress._progress else None
        assert task is not None
        assert task.description == "run-a: decisions"
        progress.done()
        assert task.completed == 1
