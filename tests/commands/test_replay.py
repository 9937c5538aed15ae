"""`hil replay`: reports, JSON, JUnit, exit status; one clear line for a bad log."""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
import shutil
from collections.abc import Callable
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from hil.bag.messages import Record
from hil.bag.reader import BagReader
from hil.bag.recorder import RecorderConfig
from hil.bag.run_info import RunInfo
from hil.commands import replay
from hil.commands.record_suite import write_bag
from hil.core.records import Decision, StateEstimate
from hil.core.samples import VelocityReference
from tests.bag.bag_streams import tree_digest

ROOT = Path(__file__).resolve().parents[2]
LOG = ROOT / "logs" / "coarse-high-seed2"
FOREIGN_BAGS = ROOT.parent / "shared" / "foreign_bags"


def run_replay(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    replay.add_arguments(parser)
    return replay.run(parser.parse_args(list(argv)))


def test_clean_log_passes_with_a_report_and_junit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    before = tree_digest(LOG)
    junit = tmp_path / "replay.xml"
    assert run_replay(str(LOG), "--junit", str(junit), "--json") == 0
    out, err = capsys.readouterr()
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["exit_code"] == 0
    assert summary["reports"][0]["checks"][0]["name"] == "decisions"
    assert "[   ok] decisions:" in err  # with --json the report goes to stderr
    assert "no regression" in err
    suite = ET.parse(junit).getroot().find("testsuite")
    assert suite is not None
    assert suite.get("failures") == "0"
    assert tree_digest(LOG) == before


def test_tampered_log_exits_1_and_names_the_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with BagReader(LOG) as reader:
        info = RunInfo.from_custom_data(reader.info.custom)
        records = [r for _, _, r in reader.records()]
    assert info is not None
    index, decision = next(
        (i, r)
        for i, r in enumerate(records)
        if isinstance(r, Decision) and len(r.safe_input_indices) >= 2
    )
    records[index] = dataclasses.replace(decision, chosen_index=-1, chosen_input=(0.0, 0.0, 0.0))
    copy = tmp_path / "tampered"
    write_bag(copy, info, records, RecorderConfig(split_s=1e9, flush_s=1e9, threaded=False))
    assert run_replay(str(copy), "--no-stack") == 1
    out = capsys.readouterr().out
    # The tampered choice is also the next decision's previous input (the cost J smooths
    # against it), so that one may differ too; the first difference is the tampered one.
    assert re.search(
        r"\[ FAIL\] decisions: [12] of \d+ decisions differ or are inconsistent, first at t="
        + f"{decision.t_ns / 1e9:.3f} s",
        out,
    )
    at = f"t={decision.t_ns / 1e9:.3f} s"
    assert f"{at}: chosen_index: -1 (none) although {len(decision.safe_inputs)} safe inputs" in out
    assert "chosen_index differ from the replay" in out
    assert "REGRESSION" in out


def test_missing_log_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run_replay(str(tmp_path / "nope")) == 2
    err = capsys.readouterr().err
    assert f"hil replay: error: {tmp_path / 'nope'}: " in err
    assert "does not exist" in err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    "name",
    [
        "mcap_cdr_test",
        "protobuf_foxglove_log.mcap",
        "split_no_metadata",
        "truncated_60pct",
        "bitflip_middle",
    ],
)
def test_foreign_log_is_one_line_and_exit_2(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    path = FOREIGN_BAGS / name
    if not path.exists():
        pytest.skip(f"{path} is not available")
    before = tree_digest(path)
    assert run_replay(str(path)) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("hil replay: error: ")]
    assert len(lines) == 1
    assert "Traceback" not in err
    assert "internal error" not in err
    assert tree_digest(path) == before


def test_log_of_another_scenario_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    copy = tmp_path / "run"
    shutil.copytree(LOG, copy)
    assert run_replay(str(copy), "--scenario", "paper") == 2
    assert "another scenario" in capsys.readouterr().err


def test_bad_tolerance_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert run_replay(str(LOG), "--tolerance", "surge=abc") == 2
    assert "'surge=abc'" in capsys.readouterr().err
    assert run_replay(str(LOG), "--pose-delay-ms", "-5") == 2
    assert "pose_delay_ns" in capsys.readouterr().err


def test_enforced_tolerance_fails_the_clean_log(capsys: pytest.CaptureFixture[str]) -> None:
    assert run_replay(str(LOG), "--no-stack", "--tolerance", "surge=0.001") == 1
    assert "[ FAIL] tracking:" in capsys.readouterr().out


def test_rerun_flag_writes_the_recording_with_replayed_decisions(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rerun.chunk import RrdReader

    assert run_replay(str(LOG), "--no-stack", "--rerun", str(tmp_path)) == 0
    rrd = tmp_path / f"{LOG.name}.replay.rrd"
    assert f"rerun: {rrd}" in capsys.readouterr().out
    store = RrdReader(rrd).store()
    with BagReader(LOG) as reader:
        n_decisions = sum(1 for _ in reader.records(["/hil/decision"]))
    chunks = store.stream().filter(content="/world/replay/safe_inputs", is_static=False).to_chunks()
    assert sum(c.num_rows for c in chunks) == n_decisions
    # The current code reproduces this log: no decision is marked as different.
    marked = store.stream().filter(content="/world/replay/differs", is_static=False).to_chunks()
    assert sum(c.num_rows for c in marked) == 0


def test_shell_glob_over_logs_replays_the_bags_and_skips_the_rest(
    capsys: pytest.CaptureFixture[str],
) -> None:
    entries = sorted((ROOT / "logs").iterdir())
    assert run_replay(*(str(p) for p in entries), "--no-stack") == 0
    out = capsys.readouterr().out
    assert f"skipped {ROOT / 'logs' / 'suite.json'}: not a bag" in out
    assert f"skipped {ROOT / 'logs' / 'README.md'}: not a bag" in out
    bags = [p for p in entries if (p / "metadata.yaml").is_file()]
    assert out.strip().splitlines()[-1].startswith(f"{len(bags)} log(s): no regression")
    # The folder itself stands for the bags in it.
    assert run_replay(str(ROOT / "logs"), "--no-stack") == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith(f"{len(bags)} log(s): no regression")


def _records() -> tuple[RunInfo, list[Record]]:
    with BagReader(LOG) as reader:
        info = RunInfo.from_custom_data(reader.info.custom)
        records: list[Record] = [r for _, _, r in reader.records()]
    assert info is not None
    return info, records


def _write(path: Path, info: RunInfo, records: list[Record]) -> Path:
    write_bag(path, info, records, RecorderConfig(split_s=1e9, flush_s=1e9, threaded=False))
    return path


def _tamper(path: Path, edit: Callable[[Decision], Decision]) -> tuple[Path, Decision]:
    """Write a copy of LOG with one decision (>= 3 safe inputs, after 10 s) edited."""
    info, records = _records()
    index, decision = next(
        (i, r)
        for i, r in enumerate(records)
        if isinstance(r, Decision) and len(r.safe_input_indices) >= 3 and r.t_ns > 10**10
    )
    records[index] = edit(decision)
    return _write(path, info, records), decision


def _other(d: Decision) -> int:
    """Position in the safe set of a safe input that is not the chosen one."""
    return next(k for k, i in enumerate(d.safe_input_indices) if i != d.chosen_index)


def _shifted(row: tuple[float, float, float]) -> tuple[float, float, float]:
    return (row[0] + 0.05, row[1], row[2])


TAMPERINGS: dict[str, tuple[Callable[[Decision], Decision], str]] = {
    # chosen_input changed to another safe input, the index kept
    "chosen input": (
        lambda d: dataclasses.replace(d, chosen_input=d.safe_inputs[_other(d)]),
        "chosen_input: recorded",
    ),
    # one safe input row edited, its index kept
    "safe input row": (
        lambda d: dataclasses.replace(
            d,
            safe_inputs=tuple(
                _shifted(row) if k == _other(d) else row for k, row in enumerate(d.safe_inputs)
            ),
        ),
        "safe_inputs[{k}]: recorded",
    ),
    # a safe input left out, consistently (index and row): only the replay can tell
    "safe set": (
        lambda d: dataclasses.replace(
            d,
            safe_inputs=tuple(r for k, r in enumerate(d.safe_inputs) if k != _other(d)),
            safe_input_indices=tuple(
                i for k, i in enumerate(d.safe_input_indices) if k != _other(d)
            ),
        ),
        "safe_input_indices differ from the replay",
    ),
    "winning": (lambda d: dataclasses.replace(d, winning=False), "winning: recorded False"),
    "value": (lambda d: dataclasses.replace(d, value=d.value + 1), "value differ from the replay"),
}


@pytest.mark.parametrize("case", sorted(TAMPERINGS))
def test_hand_edited_decision_is_a_regression_naming_time_and_field(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    edit, expected = TAMPERINGS[case]
    copy, decision = _tamper(tmp_path / "tampered", edit)
    assert run_replay(str(copy), "--no-stack") == 1
    out = capsys.readouterr().out
    at = f"t={decision.t_ns / 1e9:.3f} s"
    assert f"decisions differ or are inconsistent, first at {at}" in out
    assert f"{at}: {expected.format(k=_other(decision))}" in out
    assert out.strip().splitlines()[-1] == "1 log(s): REGRESSION"


def test_log_with_nothing_to_act_on_prints_a_clean_pass(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The estimated velocity set to the reference in force: no tracking error, so every
    # velocity envelope holds; nothing else changes. No WARN may remain (the paper's
    # figures are none).
    info, records = _records()
    reference = None
    for k, r in enumerate(records):
        if isinstance(r, VelocityReference):
            reference = r
        elif isinstance(r, StateEstimate) and reference is not None:
            records[k] = dataclasses.replace(
                r,
                surge_mps=reference.surge_mps,
                sway_mps=reference.sway_mps,
                yaw_rate_radps=reference.yaw_rate_radps,
            )
    copy = _write(tmp_path / "clean", info, records)
    assert run_replay(str(copy), "--no-stack") == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith(f"{copy}: PASS (")
    assert "WARN" not in out
    assert re.search(r"\[   ok\] contract: \d+ intervals kept their contracts", out), out
    assert out.strip().splitlines()[-1] == "1 log(s): no regression"


def test_non_bags_are_skipped_and_nothing_to_replay_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    logs = tmp_path / "logs"
    shutil.copytree(LOG, logs / "run")
    (logs / "README.md").write_text("# runs\n")
    (logs / "notes").mkdir()
    entries = sorted(str(p) for p in logs.iterdir())
    assert run_replay(*entries, "--no-stack") == 0
    out = capsys.readouterr().out
    assert f"skipped {logs / 'README.md'}: not a bag" in out
    assert f"skipped {logs / 'notes'}: a folder without bags" in out
    assert out.strip().splitlines()[-1].startswith("1 log(s): no regression")
    assert run_replay(str(logs / "README.md")) == 2
    out, err = capsys.readouterr()
    assert "hil replay: error: no bag among 1 argument(s)" in err
    assert out.strip().splitlines()[-1] == "0 log(s): ERROR: no log to replay"


def test_unreadable_wins_over_regression_and_both_are_reported(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    copy, _ = _tamper(tmp_path / "tampered", TAMPERINGS["winning"][0])
    assert run_replay(str(copy), str(tmp_path / "missing"), "--no-stack") == 2
    out, err = capsys.readouterr()
    assert f"{copy}: FAIL" in out
    assert f"hil replay: error: {tmp_path / 'missing'}: " in err
    assert out.strip().splitlines()[-1] == "2 log(s): ERROR: some logs could not be replayed"


def test_help_documents_the_exit_codes(capsys: pytest.CaptureFixture[str]) -> None:
    parser = argparse.ArgumentParser()
    replay.add_arguments(parser)
    text = parser.format_help()
    for line in ("0  no regression", "1  regression", "2  unreadable input"):
        assert line in text


def test_jsonl_has_one_line_per_interval_and_the_verdict_last(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    copy, decision = _tamper(tmp_path / "tampered", TAMPERINGS["chosen input"][0])
    out_file = tmp_path / "out" / "replay.jsonl"
    assert run_replay(str(LOG), str(copy), "--no-stack", "--jsonl", str(out_file)) == 1
    lines = [json.loads(line) for line in out_file.read_text().splitlines()]
    assert lines[-1] == {
        "type": "verdict",
        "verdict": "fail",
        "exit_code": 1,
        "logs": 2,
        "failed": 1,
        "errors": 0,
        "warned": 0,
    }
    with BagReader(LOG) as reader:
        n_decisions = sum(1 for _ in reader.records(["/hil/decision"]))
    for path, verdict in ((str(LOG), "pass"), (str(copy), "fail")):
        intervals = [x for x in lines if x["type"] == "interval" and x["log"] == path]
        assert len(intervals) == n_decisions
        assert [x["t_ns"] for x in intervals] == sorted(x["t_ns"] for x in intervals)
        (log,) = [x for x in lines if x["type"] == "log" and x["log"] == path]
        assert log["verdict"] == verdict
        assert log["intervals"] == n_decisions
    first = lines[0]
    assert set(first) >= {
        "t_ns",
        "state",
        "chosen_input",
        "successor_contained",
        "tube_contained",
        "tracking_rms",
        "tracking_max",
        "verdict",
    }
    judged = [x for x in lines if x.get("successor_contained") is not None]
    assert judged
    assert all(isinstance(x["tube_contained"], bool) for x in judged)
    (hit,) = [x for x in lines if x.get("log") == str(copy) and x.get("t_ns") == decision.t_ns]
    assert hit["verdict"] == "fail"
    assert hit["chosen_input"] != list(decision.chosen_input)
    # "-" writes to stdout; the reports then go to stderr.
    capsys.readouterr()
    assert run_replay(str(LOG), "--no-stack", "--jsonl", "-") == 0
    out, err = capsys.readouterr()
    assert json.loads(out.strip().splitlines()[-1])["type"] == "verdict"
    assert "[   ok] decisions" in err
