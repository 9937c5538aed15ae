"""`hil record-suite [DIR]`: regenerate the recorded regression suite (``logs/``) deterministically.

Runs a fixed list of simulated dockings in the coarse scenario (several starts,
a moving obstacle, injected pose and thruster outages), each a pure function
of its :class:`~hil.runs.sim_run.SimRunSpec`, records each into a bag with
one split and chunks closed at whole seconds of run time (so the bytes depend
only on the run), and writes ``suite.json`` with every run's full specification
for ``hil replay --resim``. The wall-clock synthesis times in the
``controller_ready`` event texts are left out, so regenerating with unchanged
code gives the same MCAP bytes. Before replacing a log it says what changed
against the old one (decisions, docking time, first differing decision).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shutil
import sys
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

from hil.commands.executor_cli import add_executor_arguments, executor_choice
from hil.commands.stages import Stages

if TYPE_CHECKING:  # the CLI imports every command for --help: keep numba out of it
    from hil.bag.messages import Record
    from hil.bag.recorder import RecorderConfig
    from hil.bag.run_info import RunInfo
    from hil.core.records import Event
    from hil.runs.sim_run import SimRunSpec
    from hil.runtime.trace import MemoryLog

HELP = "regenerate the recorded regression suite (logs/) and show what changed"


@dataclass(frozen=True, slots=True)
class SuiteRun:
    """One run of the suite.

    Attributes:
        name: Directory name of its log.
        spec: The simulated run.
        note: What it exercises.
    """

    name: str
    spec: SimRunSpec
    note: str


def suite() -> tuple[SuiteRun, ...]:
    """Return the runs of ``logs/``.

    Mostly the coarse scenario (the docking end of the arena), which keeps CI short; two
    runs of the paper scenario.
    """
    from hil.adapters.sim import ObstacleMotion, ThrusterOutage
    from hil.runs.sim_run import SimRunSpec
    from hil.runtime.settings import LoopConfig

    loop = LoopConfig(max_duration_s=240.0)
    return (
        SuiteRun(
            "coarse-default-seed0",
            SimRunSpec("coarse", 0, None, loop=loop),
            "the default start, bow up",
        ),
        SuiteRun(
            "coarse-low-seed1",
            SimRunSpec("coarse", 1, (0.25, -1.2, math.radians(120.0)), loop=loop),
            "start low on the right, heading up-left",
        ),
        SuiteRun(
            "coarse-high-seed2",
            SimRunSpec("coarse", 2, (0.0, -1.2, math.radians(180.0)), loop=loop),
            "start on the right below O2's end, heading left (the arena above is too narrow "
            "to turn in); its second decision ties in J (inputs 87 and 62)",
        ),
        SuiteRun(
            "coarse-moving-o2-seed3",
            SimRunSpec(
                "coarse", 3, None, loop=loop, motions=(ObstacleMotion(0, (0.0, 0.05), 4.0, 8.0),)
            ),
            "O2 moves up 0.2 m between 4 s and 8 s: re-synthesis on new layouts",
        ),
        SuiteRun(
            "coarse-faults-seed4",
            SimRunSpec(
                "coarse",
                4,
                None,
                loop=loop,
                pose_outages_s=((20.0, 1.0),),
                thruster_outages=(ThrusterOutage(30.0, 30.3),),
            ),
            "pose lost for 1 s at 20 s (hold), thruster link down 30-30.3 s",
        ),
        SuiteRun(
            "paper-default-seed0",
            SimRunSpec("paper", 0, None, loop=loop),
            "the paper scenario (160 x 120 x 60 cells), the default start",
        ),
        SuiteRun(
            "paper-high-seed1",
            SimRunSpec("paper", 1, (3.75, 1.5, math.radians(180.0)), loop=loop),
            "the paper scenario, start high on the right, heading left",
        ),
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument(
        "dir",
        nargs="?",
        type=Path,
        default=Path("logs"),
        metavar="DIR",
        help="suite directory (default: logs)",
    )
    parser.add_argument(
        "--only",
        action="append",
        default=None,
        metavar="NAME",
        help="regenerate only this run (repeatable)",
    )
    add_executor_arguments(parser, 1)
    parser.add_argument("--list", action="store_true", help="list the runs and exit")


def record_run(run: SuiteRun, out_dir: Path) -> Path:
    """Simulate `run` and write its bag to ``out_dir / run.name``; return the bag path."""
    from hil.bag.recorder import RecorderConfig
    from hil.bag.run_info import RunInfo
    from hil.runs.sim_run import run_in_sim
    from hil.runs.stack_assembly import scenario_hash
    from hil.runtime.trace import MemoryLog
    from hil.scenarios import load_scenario

    log = MemoryLog()
    run_in_sim(replace(run.spec, out_dir=None), log=log)
    scenario = load_scenario(run.spec.scenario)
    info = RunInfo.current(run.spec.scenario, scenario_hash(scenario), run.spec.seed, "sim")
    path = out_dir / run.name
    write_bag(
        path,
        info,
        memory_records(log, wall_times=False),
        RecorderConfig(split_s=1e9, flush_s=1e9, threaded=False),
    )
    return path


_WALL_TIME = re.compile(r" in \d+\.\d+ s(?=$| \()")


def memory_records(log: MemoryLog, *, wall_times: bool = True) -> list[Record]:
    """Return every record of a :class:`~hil.runtime.trace.MemoryLog`, sorted by time (stable).

    Args:
        log: The run's records.
        wall_times: Keep the wall-clock synthesis time in ``controller_ready``
            event texts and records; False drops it (NaN in the records), the only
            part of a simulated run that is not a function of its specification.
    """
    from hil.core.records import Event, ForceCommand, StateEstimate
    from hil.core.samples import VelocityReference

    records: list[Record] = [*log.poses, *log.imus]
    records += [
        StateEstimate(t, *(float(v) for v in eta), *(float(v) for v in nu))
        for t, eta, nu in log.estimates
    ]
    records += [VelocityReference(t, *(float(v) for v in nu)) for t, nu in log.velocity_references]
    records += [ForceCommand(t, *(float(v) for v in tau)) for t, tau in log.forces]
    records += [*log.thruster_commands, *log.decisions, *log.layouts]
    records += [
        Event(
            t,
            level,
            code,
            text if wall_times or code != "controller_ready" else _WALL_TIME.sub("", text),
        )
        for t, level, code, text in log.events
    ]
    records += [
        c if wall_times else replace(c, seconds=math.nan) for c in log.controllers
    ]
    records.sort(key=lambda r: r.t_ns)
    return records


def write_bag(
    path: Path,
    info: RunInfo,
    records: Iterable[Record],
    config: RecorderConfig | None = None,
    flush_every_ns: int | None = 1_000_000_000,
) -> None:
    """Write `records` to a new bag at `path` with the real recorder.

    Args:
        path: New bag directory.
        info: The run description (:class:`~hil.bag.run_info.RunInfo`).
        records: Samples and records (:data:`hil.bag.messages.Record`), in time order.
        config: Recorder configuration (:class:`~hil.bag.recorder.RecorderConfig`).
        flush_every_ns: Close a chunk at every multiple of this run time (ns), as
            the live recorder does every flush interval, so that a truncated
            copy keeps every stream up to the cut; None writes all at close.
    """
    from hil.bag.recorder import Recorder

    with Recorder(path, info, config) as recorder:
        boundary = flush_every_ns
        for record in records:
            while boundary is not None and flush_every_ns and record.t_ns >= boundary:
                recorder.flush()
                boundary += flush_every_ns
            recorder.record(record)


def describe_change(old: Path, new: Path) -> str:
    """Return one line saying how the run at `new` differs from the one at `old`."""
    from hil.bag.run_data import load_run

    try:
        before = load_run(old)
    except Exception as err:  # an unreadable old log is replaced; say why
        return f"old log unreadable ({str(err).splitlines()[0] if str(err) else err!r})"
    after = load_run(new)

    def docked(events: Iterable[Event]) -> str:
        times = [e.t_ns / 1e9 for e in events if e.code == "docked"]
        return f"docked at {times[0]:.2f} s" if times else "not docked"

    pairs = list(zip(before.decisions, after.decisions, strict=False))
    first = next(
        (
            a.t_ns
            for a, b in pairs
            if (a.t_ns, a.chosen_index, a.value) != (b.t_ns, b.chosen_index, b.value)
        ),
        None,
    )
    if first is None and len(before.decisions) == len(after.decisions):
        same = "unchanged decisions"
    else:
        where = f"first at t={first / 1e9:.2f} s" if first is not None else "in count only"
        same = f"decisions changed ({where})"
    return (
        f"{same}: {len(before.decisions)} -> {len(after.decisions)} decisions, "
        f"{docked(before.events)} -> {docked(after.events)}"
    )


def _manifest(runs: Iterable[SuiteRun], existing: dict[str, object]) -> dict[str, object]:
    from hil.runs.sim_run import spec_to_json

    entries = dict(existing)
    for run in runs:
        entries[run.name] = {**spec_to_json(run.spec), "note": run.note}
    return {"format": 1, "runs": dict(sorted(entries.items()))}


def record_files(run: SuiteRun) -> dict[str, bytes]:
    """Record `run` in a temporary folder; return its bag's files by relative path.

    The job of :func:`hil.runs.fanout.fan_out`: a worker may be another machine, so the
    bag comes back as bytes and is written into the suite here.
    """
    with tempfile.TemporaryDirectory(prefix="hil-record-") as tmp:
        path = record_run(run, Path(tmp))
        return {str(p.relative_to(path)): p.read_bytes()
                for p in sorted(path.rglob("*")) if p.is_file()}


def _encode_run(run: SuiteRun) -> object:
    from hil.runs.sim_run import spec_to_json

    return {"name": run.name, **spec_to_json(run.spec)}


def _encode_files(files: dict[str, bytes]) -> object:
    return sorted(files)


def _no_decode(data: object) -> dict[str, bytes]:
    raise TypeError(f"recorded bags are not read back from a results file: {data!r}")


def run(args: argparse.Namespace) -> int:
    """Regenerate the suite; return 0, or 2 on bad arguments or a failed run."""
    Stages("hil record-suite").say("loading the suite's manifest and the simulator ...")
    from hil.replay.resim import MANIFEST
    from hil.runs.backends import require_backend
    from hil.runs.errors import ExecutorError

    if args.list:
        for item in suite():
            print(f"{item.name}: {item.note}")
        return 0
    runs = suite()
    chosen = [r for r in runs if args.only is None or r.name in args.only]
    unknown = sorted(set(args.only or ()) - {r.name for r in runs})
    try:
        require_backend(executor_choice(args))
    except ExecutorError as err:
        print(f"hil record-suite: error: {err}", file=sys.stderr)
        return 2
    if unknown or args.workers < 1:
        print(
            f"hil record-suite: error: unknown run(s) {unknown!r} or --workers < 1; "
            f"runs: {[r.name for r in runs]!r}",
            file=sys.stderr,
        )
        return 2
    target: Path = args.dir
    target.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".record-suite-", dir=target) as staging:
        from hil.runs.backends import open_executor
        from hil.runs.campaign import warm_sim
        from hil.runs.errors import ExecutorError
        from hil.runs.fanout import Job, fan_out

        job: Job[SuiteRun, dict[str, bytes]] = Job(
            "record-suite", record_files, _encode_run, _encode_files, _no_decode,
            partial(warm_sim, ("coarse",)))

        def write(index: int, outcome: object) -> None:
            if isinstance(outcome, dict):
                print(f"recorded {chosen[index].name}", flush=True)
                for relative, data in outcome.items():
                    path = Path(staging) / chosen[index].name / relative
                    path.parent.mkdir(parents=True, exist_ok=True)
                    path.write_bytes(data)

        try:
            with open_executor(executor_choice(args), job.warm) as executor:
                out = fan_out(job, chosen, executor, report=write)
        except ExecutorError as err:
            print(f"hil record-suite: error: {err}", file=sys.stderr)
            return 2
        if out.failures or out.stopped:
            why = out.stopped or "; ".join(f"{chosen[f.index].name}: {f.error}"
                                           for f in out.failures)
            print(f"hil record-suite: error: a run failed: {why}", file=sys.stderr)
            return 2
        for item in chosen:
            new, old = Path(staging) / item.name, target / item.name
            change = describe_change(old, new) if old.exists() else "new"
            size_kb = sum(p.stat().st_size for p in new.rglob("*") if p.is_file()) / 1024
            print(f"{item.name}: {change} ({size_kb:.0f} KiB)")
            if old.exists():
                shutil.rmtree(old)
            shutil.move(str(new), str(old))
    manifest_path = target / MANIFEST
    existing: dict[str, object] = {}
    if manifest_path.is_file():
        try:
            existing = dict(json.loads(manifest_path.read_text()).get("runs", {}))
        except (ValueError, AttributeError):
            existing = {}
    manifest_path.write_text(json.dumps(_manifest(chosen, existing), indent=2) + "\n")
    print(f"wrote {len(chosen)} log(s) and {manifest_path}")
    return 0
