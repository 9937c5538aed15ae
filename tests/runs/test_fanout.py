"""The fan-out on local processes: failures with their spec, killed workers retried, resume."""

import os
from pathlib import Path

import pytest

from hil.runs.executor import LocalExecutor
from hil.runs.fanout import Failure, Job, fan_out
from hil.runs.results import Plan, ResultStream


def _square(item: tuple[str, int]) -> int:
    """Square item[1]; 3 raises; with a marker path, the first call for 5 kills its process."""
    marker, value = item
    if value == 3:
        raise ValueError(f"three is refused ({value!r})")
    if value == 5 and marker and not Path(marker).exists():
        Path(marker).touch()
        os._exit(1)  # the worker dies under the run, as if killed
    return value * value


def _same(value: object) -> object:
    return value


def _as_int(value: object) -> int:
    assert isinstance(value, int)
    return value


def _encode(item: tuple[str, int]) -> object:
    return {"value": item[1]}


JOB: Job[tuple[str, int], int] = Job("test", _square, _encode, _same, _as_int)


def test_a_failed_run_is_reported_with_its_spec_and_a_resume_reruns_only_it(
        tmp_path: Path) -> None:
    specs = [("", i) for i in range(6)]
    path = tmp_path / "r.jsonl"
    plan = Plan.of("test", [_encode(s) for s in specs])
    ended: list[tuple[int, object]] = []
    with ResultStream(path, plan) as stream, LocalExecutor(1) as local:
        out = fan_out(JOB, specs, local, stream, lambda i, o: ended.append((i, o)))
    assert out.results == [0, 1, 4, None, 16, 25]
    assert out.failures == [Failure(3, {"value": 3}, "ValueError: three is refused (3)")]
    assert (3, out.failures[0]) in ended
    assert '"error": "ValueError: three is refused (3)", "run": 3, "spec": {"value": 3}' in \
        path.read_text()
    calls: list[int] = []
    with ResultStream(path, plan, resume=True) as stream, LocalExecutor(1) as local:
        again = fan_out(JOB, specs, local, stream, lambda i, _o: calls.append(i))
    assert again.resumed == 5
    assert calls == [3]  # only the failed run ran again (and failed again)
    assert again.results == out.results


@pytest.mark.parametrize("workers", [2])
def test_a_killed_pool_process_loses_no_run(tmp_path: Path, workers: int) -> None:
    marker = str(tmp_path / "killed-once")
    specs = [(marker, i) for i in range(8) if i != 3]
    with LocalExecutor(workers) as pool:
        out = fan_out(JOB, specs, pool)
    assert Path(marker).exists()  # a process did die
    assert out.retried >= 1
    assert not out.failures
    assert out.results == [v * v for _, v in specs]
