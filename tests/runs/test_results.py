import json
from pathlib import Path

import pytest

from hil.runs.errors import ResultsError
from hil.runs.results import Plan, ResultStream

PLAN = Plan.of("campaign", [{"seed": i} for i in range(4)])


def test_runs_stream_as_lines_and_a_resume_reads_them_back(tmp_path: Path) -> None:
    path = tmp_path / "r.jsonl"
    with ResultStream(path, PLAN) as stream:
        stream.record(2, {"docked": True})
        stream.record_failure(0, {"seed": 0}, "ValueError: no")
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    assert lines[0] == {"hil_results": 1, "job": "campaign", "plan": PLAN.digest, "runs": 4}
    assert lines[1:] == [{"run": 2, "result": {"docked": True}},
                         {"run": 0, "error": "ValueError: no", "spec": {"seed": 0}}]
    with ResultStream(path, PLAN, resume=True) as again:
        assert again.finished == {2: {"docked": True}}  # the failed run is run again
        again.record(0, {"docked": False})
    with ResultStream(path, PLAN, resume=True) as third:
        assert third.finished == {0: {"docked": False}, 2: {"docked": True}}


def test_a_line_cut_by_a_kill_is_dropped_and_the_file_stays_whole(tmp_path: Path) -> None:
    path = tmp_path / "r.jsonl"
    with ResultStream(path, PLAN) as stream:
        stream.record(1, [1, 2])
    with path.open("a") as f:
        f.write('{"run": 3, "resu')
    with ResultStream(path, PLAN, resume=True) as again:
        assert again.dropped_partial
        assert again.finished == {1: [1, 2]}
        again.record(3, [3])
    assert [json.loads(line)["run"] for line in path.read_text().splitlines()[1:]] == [1, 3]


def test_another_campaign_or_an_existing_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "r.jsonl"
    ResultStream(path, PLAN).open().close()
    with pytest.raises(ResultsError, match="exists: pass --resume"):
        ResultStream(path, PLAN).open()
    other = Plan.of("campaign", [{"seed": i} for i in range(5)])
    with pytest.raises(ResultsError, match="holds another 'campaign' of 4 runs"):
        ResultStream(path, other, resume=True).open()
    path.write_text("hello\n")
    with pytest.raises(ResultsError, match="no hil results file"):
        ResultStream(path, PLAN, resume=True).open()
    assert Plan.of("sweep", [{"seed": 0}]).digest != Plan.of("campaign", [{"seed": 0}]).digest
