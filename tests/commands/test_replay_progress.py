"""Progress of a replay: shown on a terminal only, never in the way of the reports."""

from __future__ import annotations

from collections.abc import Callable
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


def test_a_replay_in_this_process_shows_each_log_and_its_steps(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from hil.cli import main

    shown: list[tuple[str, str]] = []
    original = ReplayProgress.step

    def step(self: ReplayProgress, log: Path) -> Callable[[str], None]:
        show = original(self, log)

        def record(name: str) -> None:
            shown.append((log.name, name))
            show(name)

        return record

    monkeypatch.setattr(ReplayProgress, "step", step)
    log = Path(__file__).parents[2] / "logs" / "coarse-default-seed0"
    assert main(["replay", str(log), "--no-stack"]) == 0
    assert "PASS" in capsys.readouterr().out
    steps = [name for where, name in shown if where == log.name]
    assert steps[0] == "load"
    assert {"decisions", "tracking", "contract"} <= set(steps)
    assert "stack" not in steps  # --no-stack: the step shown is the step made
