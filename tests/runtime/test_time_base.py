"""One clock per run: every recorded topic on the run's time base, the bag's span true.

The scenario's obstacle layout is known before any run (stamped 0); a run on wall
time (the vessel) or on a /clock that started before the stack must still record
it on its own clock, or the bag's start is 0 and its duration decades.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.adapters.obstacles import StaticObstacleSource
from hil.bag.reader import BagReader
from hil.bag.recorder import Recorder
from hil.core.samples import ImuSample, PoseSample, ThrusterCommand
from hil.runs.stack_assembly import build_runtime, default_start, synthesizer_for
from hil.runtime.assembly import layout_from_scenario
from hil.runtime.loop import World
from hil.runtime.resynthesis import ResynthesisMode
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.runtime.stopping import REST_HOLD_S
from hil.scenarios import load_scenario


class _Clock:
    def __init__(self, start_ns: int) -> None:
        self.t_ns = start_ns

    def now_ns(self) -> int:
        return self.t_ns

    def sleep_until(self, t_ns: int) -> None:
        self.t_ns = max(self.t_ns, t_ns)


class _Pose:
    """A vessel at rest at `pose`, measured every tick on the world's clock."""

    def __init__(self, clock: _Clock, pose: tuple[float, float, float]) -> None:
        self.clock = clock
        self.pose = pose

    def poll(self) -> list[PoseSample]:
        return [PoseSample(self.clock.now_ns(), *self.pose)]


class _NoImu:
    def poll(self) -> list[ImuSample]:
        return []


class _Sink:
    def send(self, command: ThrusterCommand) -> None:
        pass


@pytest.mark.parametrize(
    "start_ns",
    [
        pytest.param(0, id="sim"),
        pytest.param(1_796_011_134 * NS_PER_S + 123_456_789, id="wall"),
        pytest.param(7_690_000_000, id="clock-joined-late"),
    ],
)
def test_every_topic_is_on_the_run_clock(
    start_ns: int, tmp_path: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    scenario = load_scenario("coarse")
    clock = _Clock(start_ns)
    layout = layout_from_scenario(scenario)
    assert layout.t_ns == 0  # known before the run, on no clock at all
    world = World(clock, _Pose(clock, default_start(scenario)), _NoImu(),
                  StaticObstacleSource(layout), _Sink())
    loop = LoopConfig(max_duration_s=3.0, resynthesis_period_s=None)
    out = tmp_path / "run"
    synthesizer = synthesizer_for(scenario, tmp_path_factory.getbasetemp() / "tables")
    with Recorder(out) as recorder:
        runtime = build_runtime(scenario, world, recorder, loop, synthesizer,
                                ResynthesisMode.INLINE)
        stats = runtime.run()
    assert stats.start_ns == start_ns
    with BagReader(out) as reader:
        info = reader.info
        first: dict[str, int] = {}
        for raw in reader.messages():
            first.setdefault(raw.topic, raw.t_ns)
    assert info.start_ns == start_ns
    assert first["/hil/obstacles"] == start_ns
    assert min(first.values()) == start_ns
    # The span is the run's: 3 s limit, one tick past it, braking to rest (the vessel is
    # at rest: REST_HOLD_S), the final zero command.
    assert info.duration_ns == stats.end_ns - start_ns
    assert 3 * NS_PER_S < info.duration_ns < (3.2 + REST_HOLD_S) * NS_PER_S
    metadata = (out / "metadata.yaml").read_text()
    assert f'"nanoseconds_since_epoch": {start_ns}' in metadata
