"""Replay time of a recorded ~3-minute docking run, and bag decode rate against plain rosbags.

`python -m bench replay [--log PATH] [--scenario NAME] [--repeat N]`

Workload: real recorded runs totalling at least 3 simulated minutes. Without
`--log`, dockings in the paper scenario (seeds 0, 1, ..., start varied) are simulated
and recorded first (not timed) until they add up to 180 s; a paper docking in
simulation takes 60-90 s, shorter than the tank's 2.67 min.

Replay rows (wall seconds, best of N, each with a fresh controller cache so the
synthesis for the recorded layout is included, as `hil replay` pays it):
open loop with the full stack re-run (the default of `hil replay`), and the
decision and tracking checks alone. Ratios against the issue's limit (10 s) and
goal (3 s) for a 3-minute run, and the run's own simulated length.

Decode rows (messages per second over every message of the bag): rosbags
`AnyReader` + `deserialize_cdr` (baseline), and `hil.bag.run_data.load_run`
(what the replay reads: numpy columns for the fixed-layout topics, records for
decisions, layouts and events), with the ratio to the baseline.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path


def _record(scenario: str, seed: int, out: Path) -> Path:
    from hil.commands.record_suite import SuiteRun, record_run
    from hil.runs.sim_run import SimRunSpec
    from hil.runs.stack_assembly import default_start
    from hil.runtime.settings import LoopConfig
    from hil.scenarios import load_scenario

    x, y, psi = default_start(load_scenario(scenario))
    start = (x - 0.1 * (seed % 3), y + 0.25 * (seed % 2), psi)
    spec = SimRunSpec(scenario, seed, start, loop=LoopConfig(max_duration_s=400.0))
    return record_run(SuiteRun(f"{scenario}-seed{seed}", spec, "bench"), out)


def _rosbags_rate(paths: list[Path]) -> tuple[int, float]:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    start = time.perf_counter()
    n = 0
    for path in paths:
        with AnyReader([path], default_typestore=store) as reader:
            for connection, _, raw in reader.messages():
                reader.deserialize(raw, connection.msgtype)
                n += 1
    return n, time.perf_counter() - start


def _hil_rate(paths: list[Path]) -> tuple[int, float]:
    from hil.bag.reader import describe
    from hil.bag.run_data import load_run

    n = sum(describe(path).message_count for path in paths)
    start = time.perf_counter()
    for path in paths:
        load_run(path)
    return n, time.perf_counter() - start


def _replay_s(paths: list[Path], stack: bool) -> tuple[float, str]:
    from hil.replay.controllers import ScenarioCache
    from hil.replay.options import ReplayOptions
    from hil.replay.replayer import replay_log

    start = time.perf_counter()
    statuses = []
    for path in paths:  # a fresh cache per log: each pays its own synthesis
        report = replay_log(path, ReplayOptions(stack=stack), ScenarioCache())
        statuses.append(
            " ".join(f"{c.name}={c.status.value}" for c in report.checks) or report.error
        )
    return time.perf_counter() - start, "; ".join(sorted(set(statuses)))


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print the tables."""
    parser = argparse.ArgumentParser(prog="python -m bench replay", description=__doc__)
    parser.add_argument("--log", type=Path, default=None, help="recorded run to replay")
    parser.add_argument("--scenario", default="paper", help="scenario to record without --log")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-replay-") as tmp:
        from hil.bag.run_data import load_run

        paths: list[Path] = [args.log] if args.log is not None else []
        sim_s = sum(load_run(p).last_stamp_ns / 1e9 for p in paths)
        seed = 0
        while args.log is None and sim_s < 180.0 and seed < 6:
            t0 = time.perf_counter()
            paths.append(_record(args.scenario, seed, Path(tmp)))
            sim_s += load_run(paths[-1]).last_stamp_ns / 1e9
            print(f"recorded {paths[-1].name} in {time.perf_counter() - t0:.1f} s (not timed)")
            seed += 1
        runs = [load_run(p) for p in paths]
        print(
            f"logs: {len(paths)} ({sim_s:.1f} s simulated, "
            f"{sum(r.info.message_count for r in runs)} messages, "
            f"{sum(len(r.decisions) for r in runs)} decisions)\n"
        )
        _replay_s(paths[:1], stack=False)  # load the compiled kernels once
        per = 180.0 / sim_s
        print(
            f"{'replay (scaled to a 180 s run)':<42}{'wall s':>9}{'/ 10 s':>9}{'/ 3 s':>8}"
            f"{'x real time':>13}"
        )
        for label, stack in (
            ("open loop, stack re-run (default)", True),
            ("decisions + tracking only", False),
        ):
            times = [_replay_s(paths, stack) for _ in range(max(1, args.repeat))]
            best = min(t for t, _ in times) * per
            print(
                f"{label:<42}{best:>9.2f}{best / 10:>9.2f}{best / 3:>8.2f}"
                f"{180.0 / best:>13.1f}   ({times[0][1]})"
            )
        print(f"\n{'decode every message':<42}{'msgs':>9}{'s':>9}{'msgs/s':>10}{'ratio':>8}")
        rows = []
        for label, fn in (
            ("rosbags AnyReader + deserialize_cdr", _rosbags_rate),
            ("hil load_run (columns + records)", _hil_rate),
        ):
            best_s, n = min(fn(paths)[::-1] for _ in range(max(1, args.repeat)))
            rows.append((label, n, best_s))
        base = rows[0][1] / rows[0][2]
        for label, n, s in rows:
            print(f"{label:<42}{n:>9}{s:>9.3f}{n / s:>10.0f}{n / s / base:>8.2f}")
    return 0
