"""Rerun export of a real short run, read back with Rerun's own reader.

Row counts and values are checked against the bag, read independently with
:class:`BagReader` (the run itself: see ``conftest.py``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from rerun.chunk import RrdReader

from hil.bag.reader import BagReader
from hil.bag.run_data import load_run
from hil.core.samples import PoseSample, VelocityReference
from hil.views.controller_view import controller_view, scenario_for
from hil.views.rerun_export import write_rrd
from hil.views.rerun_world import decisions_differ
from tests.views.rrd_store import Exported, column, first, rows


def test_the_recording_has_the_arena_vessel_controller_and_plots(exported: Exported) -> None:
    paths = set(exported.store.schema().entity_paths())
    expected = {
        "/world/arena/boundary",
        "/world/arena/target/T1",
        "/world/arena/target/T2",
        "/world/arena/obstacles/real",
        "/world/arena/obstacles/inflated",
        "/world/vessel",
        "/world/vessel/hull",
        "/world/pose_samples",
        "/world/trajectory",
        "/world/controller/safe_inputs",
        "/world/controller/chosen_input",
        "/world/controller/winning_set",
        "/plots/velocity/surge/commanded",
        "/plots/velocity/yaw_rate/estimated",
        "/plots/tracking_error/sway/error",
        "/plots/tracking_error/sway/envelope",
        "/plots/thrusters/commands",
        "/plots/thrusters/azimuth_deg",
        "/plots/value",
        "/plots/synthesis_time_s",
        "/events",
    }
    assert expected <= paths, sorted(expected - paths)
    assert RrdReader(exported.rrd).blueprints(), "the blueprint is sent with the recording"


def test_one_row_per_pose_decision_layout_and_event(exported: Exported) -> None:
    run, store = exported.run, exported.store
    with BagReader(exported.bag) as reader:
        counts = {t.name: t.message_count for t in reader.info.topics}
    n_pose = counts["/voyager/measurement/pose"]
    n_decisions = counts["/hil/decision"]
    assert n_pose > 100
    assert n_decisions >= 5
    assert rows(store, "/world/vessel") == n_pose
    assert rows(store, "/world/pose_samples") == n_pose
    assert rows(store, "/world/controller/safe_inputs") == n_decisions
    assert rows(store, "/world/controller/chosen_input") == n_decisions
    assert rows(store, "/world/controller/winning_set") == n_decisions
    assert rows(store, "/plots/value") == n_decisions
    assert rows(store, "/world/arena/obstacles/real") == counts["/hil/obstacles"] == 2
    assert rows(store, "/events") == counts["/hil/events"] == len(run.events)
    assert rows(store, "/plots/synthesis_time_s") == 2  # the first controller and one swap


def test_logged_values_match_the_bag(exported: Exported) -> None:
    with BagReader(exported.bag) as reader:
        poses = [r for _, _, r in reader.records(["/hil/pose"])]
        refs = [r for _, _, r in reader.records(["/hil/velocity/command"])]
    pose_rows = [(p.t_ns, p.x_m, p.y_m) for p in poses if isinstance(p, PoseSample)]
    sway_rows = [(r.t_ns, r.sway_mps) for r in refs if isinstance(r, VelocityReference)]
    assert len(pose_rows) == len(poses)
    assert len(sway_rows) == len(refs)
    t, translations = column(exported.store, "/world/vessel", "Transform3D:translation")
    assert t.tolist() == [row[0] for row in pose_rows]
    got = np.array([first(row) for row in translations])
    want = np.array([[x, y, 0.0] for _, x, y in pose_rows])
    np.testing.assert_allclose(got, want, atol=1e-5)  # float32 in Rerun
    t, scalars = column(exported.store, "/plots/velocity/sway/commanded", "Scalars:scalars")
    assert t.tolist() == [row[0] for row in sway_rows]
    got_sway = np.array([first(s) for s in scalars], dtype=np.float64)
    np.testing.assert_allclose(got_sway, np.array([v for _, v in sway_rows]))


def test_safe_input_arcs_start_at_the_decision_state(exported: Exported) -> None:
    decisions = exported.run.decisions
    t, strips = column(exported.store, "/world/controller/safe_inputs", "LineStrips3D:strips")
    assert t.tolist() == [d.t_ns for d in decisions]
    for d, row in zip(decisions, strips, strict=True):
        assert isinstance(row, list)
        assert len(row) == len(d.safe_inputs)
        for strip in row:
            np.testing.assert_allclose(strip[0][:2], d.state[:2], atol=1e-5)


def test_winning_set_resynthesized_for_the_recorded_layout_matches_each_decision(
    exported: Exported,
) -> None:
    view = controller_view(exported.run, exported.scenario)
    assert view.note == ""
    regular = 0
    for decision, slice_ in zip(exported.run.decisions, view.slices, strict=True):
        assert slice_ is not None, decision
        cell = slice_.grid.cell_of(decision.state)
        assert cell is not None, decision
        assert slice_.heading_cell == cell[2], decision
        # The slice is the layer of the reference in force at the decision.
        assert slice_.reference_index == decision.reference_index, decision
        if decision.first or decision.value == 0.0:
            continue  # a first decision's value is not its layer's (decision_value)
        regular += 1
        got = float(slice_.values[cell[0], cell[1]])
        assert got == decision.value, (got, decision)
    assert regular >= 3


def test_winning_set_pixels_put_the_decision_cell_at_its_place(exported: Exported) -> None:
    decisions = exported.run.decisions
    view = controller_view(exported.run, exported.scenario)
    _, data = column(exported.store, "/world/controller/winning_set", "GridMap:data")
    _, translation = column(exported.store, "/world/controller/winning_set", "GridMap:translation")
    for d, s, blob, corner in zip(decisions, view.slices, data, translation, strict=True):
        assert s is not None
        grid = s.grid
        pixels = np.asarray(first(blob), dtype=np.uint8).reshape(grid.ny, grid.nx, 4)
        np.testing.assert_allclose(np.asarray(first(corner))[:2], [grid.x_min_m, grid.y_min_m])
        cell = grid.cell_of(d.state)
        assert cell is not None
        # The first row is drawn at the top: cell (i, j) is pixel [ny - 1 - j, i].
        assert pixels[grid.ny - 1 - cell[1], cell[0], 3] > 0  # the vessel's cell is winning
        grey = np.all(pixels == (90, 90, 90, 150), axis=-1)
        assert not np.array_equal(s.obstacles, s.obstacles[:, ::-1])  # a flip would show
        np.testing.assert_array_equal(grey, s.obstacles.T[::-1])


def test_replayed_decisions_are_shown_beside_and_differences_marked(
    exported: Exported, tmp_path: Path
) -> None:
    recorded = exported.run.decisions
    changed = 2
    replayed = list(recorded)
    replayed[changed] = dataclasses.replace(
        recorded[changed], safe_input_indices=(), safe_inputs=(), chosen_index=-1
    )
    rrd = tmp_path / "replay.rrd"
    write_rrd(exported.run, rrd, exported.scenario, None, replayed=replayed)
    store = RrdReader(rrd).store()
    assert decisions_differ(recorded[changed], replayed[changed])
    assert not decisions_differ(recorded[0], replayed[0])
    assert rows(store, "/world/replay/safe_inputs") == len(replayed)
    t, marks = column(store, "/plots/replay/differs", "Scalars:scalars")
    assert t.tolist() == [d.t_ns for d in replayed]
    assert [first(m) for m in marks] == [float(i == changed) for i in range(len(replayed))]
    t, _ = column(store, "/world/replay/differs", "Points3D:positions")
    assert t.tolist() == [recorded[changed].t_ns]
    assert rows(store, "/events/replay") == 1


def test_a_spent_synthesis_budget_leaves_later_layouts_without_a_slice(exported: Exported) -> None:
    view = controller_view(exported.run, exported.scenario, budget_s=0.0)
    second = exported.run.layouts[1].t_ns
    for decision, slice_ in zip(exported.run.decisions, view.slices, strict=True):
        layout = exported.run.layout_at(decision.t_ns)
        assert layout is not None
        assert (slice_ is None) == (layout.t_ns == second)
    assert "budget" in view.note


def test_a_bare_mcap_file_finds_its_scenario_by_the_decisions_hash(exported: Exported) -> None:
    # The recorder's splits depend on timing: take the biggest, which holds decisions.
    biggest = max(exported.bag.glob("*.mcap"), key=lambda p: p.stat().st_size)
    bare = load_run(biggest)
    assert bare.run is None
    assert bare.decisions
    scenario, note = scenario_for(bare)
    assert scenario == exported.scenario
    assert "same hash" in note


def test_obstacles_axes_and_path_ends_are_named(exported: Exported) -> None:
    times, labels = column(exported.store, "/world/arena/obstacles/names", "Points3D:labels")
    assert len(times) == len(exported.run.layouts)
    assert all(row == [o.name for o in exported.scenario.obstacles] for row in labels)
    chunks = exported.store.stream().filter(is_static=True).to_chunks()
    static = {c.entity_path: c.to_record_batch() for c in chunks}
    assert static["/world/arena/axes"].column("Arrows3D:labels").to_pylist()[0] == [
        "x north",
        "y east",
    ]
    ends = static["/world/trajectory/ends"]
    assert ends.column("Points3D:labels").to_pylist()[0] == ["start", "end"]
