"""The committed suite of recorded runs and helpers to replay or tamper with them."""

from __future__ import annotations

from pathlib import Path

from hil.bag.messages import Record
from hil.bag.reader import BagReader
from hil.bag.recorder import RecorderConfig
from hil.bag.run_info import RunInfo
from hil.commands.record_suite import write_bag
from hil.replay.controllers import ScenarioCache
from hil.replay.options import ReplayOptions
from hil.replay.regression import LogReport
from hil.replay.replayer import replay_log
from tests.bag.bag_streams import tree_digest

LOGS = Path(__file__).resolve().parents[2] / "logs"
SUITE_LOGS = sorted(p for p in LOGS.iterdir() if (p / "metadata.yaml").is_file())
REFERENCE = LOGS / "coarse-high-seed2"  # the shortest run of the suite
CONFIG = RecorderConfig(split_s=1e9, flush_s=1e9, threaded=False)


def replay_unmodified(path: Path, caches: ScenarioCache, **options: object) -> LogReport:
    """Replay `path` with `options` and check the log was left as it was."""
    before = tree_digest(path) if path.exists() else {}
    report = replay_log(path, ReplayOptions(**options), caches)  # type: ignore[arg-type]
    after = tree_digest(path) if path.exists() else {}
    assert after == before, "replay modified its input"
    return report


def rewrite(src: Path, dst: Path, edit: dict[int, Record]) -> Path:
    """Copy a log record by record through the real recorder, replacing records by index."""
    with BagReader(src) as reader:
        info = RunInfo.from_custom_data(reader.info.custom)
        records = [r for _, _, r in reader.records()]
    assert info is not None
    for i, record in edit.items():
        records[i] = record
    write_bag(dst, info, records, CONFIG)
    return dst
