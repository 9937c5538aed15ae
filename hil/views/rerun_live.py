"""Stream a run to Rerun while it goes on (``hil run --rerun``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import rerun as rr

from hil.bag.run_data import Layout
from hil.core.arrays import FloatArray
from hil.core.geometry import yaw_quaternions
from hil.core.records import ControllerReady, Decision, EventLevel
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, ThrusterCommand
from hil.core.tracking import tracking_error
from hil.replay.intervals import budget_class, envelope_bound
from hil.runtime.protocols import RunLog
from hil.scenarios import Scenario
from hil.views.blueprint import blueprint
from hil.views.controller_view import inflated_outlines, obstacle_names
from hil.views.rerun_export import start_viewer
from hil.views.rerun_style import (
    APPLICATION_ID,
    AXES,
    LEVELS,
    TIMELINE,
    closed_strip,
    decision_strips,
    finite_or_nan,
    log_styles,
    rectangle_xy,
)
from hil.views.rerun_world import log_arena, log_hull


class LiveRerunLog:
    """A RunLog that streams every record to Rerun while the run goes on.

    Uses the entity paths and blueprint of the post-run export, row by row
    (``rr.log`` at the record's time), and forwards every call to `inner` (the
    recorder, say) first, so a live view never costs the recorded data. The
    winning set is not shown live (the runtime's controller is not a record).

    Args:
        rec: The recording stream (already spawned, connected or saving).
        scenario: The run's scenario (arena, hull, tau, transient budget, inflation).
        inner: The log to forward to; None for none.
    """

    def __init__(
        self, rec: rr.RecordingStream, scenario: Scenario, inner: RunLog | None = None
    ) -> None:
        self.rec = rec
        self.scenario = scenario
        self.inner = inner
        # The last two decisions (ns, budget class): the envelope of the one in force.
        self._decided: list[tuple[int, int | None]] = []
        self._nu_ref: tuple[int, FloatArray] | None = None  # (stamp ns, (3,)) in force
        self._pending: tuple[int, FloatArray] | None = None  # estimate awaiting its error
        log_styles(rec)
        log_arena(rec, scenario)
        log_hull(rec, scenario)

    @staticmethod
    def open(
        scenario: Scenario,
        *,
        spawn: bool = False,
        save: Path | None = None,
        inner: RunLog | None = None,
        recording_id: str | None = None,
    ) -> LiveRerunLog:
        """Return a live log that spawns a viewer and/or saves to `save` (an .rrd file)."""
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
        if spawn:
            start_viewer(rec, scenario)
        if save is not None:
            # Save beside the viewer: set_sinks replaces the sinks, so name both.
            sinks: list[rr.FileSink | rr.GrpcSink] = [rr.FileSink(str(save))]
            if spawn:
                sinks.append(rr.GrpcSink())
            rec.set_sinks(*sinks, default_blueprint=blueprint(scenario))
        return LiveRerunLog(rec, scenario, inner)

    def _at(self, t_ns: int) -> None:
        self.rec.set_time(TIMELINE, duration=np.timedelta64(int(t_ns), "ns"))

    def pose(self, sample: PoseSample) -> None:
        """Move the body frame and add a pose point."""
        if self.inner is not None:
            self.inner.pose(sample)
        self._at(sample.t_ns)
        position = [sample.x_m, sample.y_m, 0.0]
        quaternion = yaw_quaternions(np.array([sample.yaw_rad]))[0]
        self.rec.log("world/vessel", rr.Transform3D(translation=position, quaternion=quaternion))
        self.rec.log("world/pose_samples", rr.Points3D([position]))

    def imu(self, sample: ImuSample) -> None:
        """Forward only: the IMU is not drawn."""
        if self.inner is not None:
            self.inner.imu(sample)

    def estimate(self, t_ns: int, eta: FloatArray, nu: FloatArray) -> None:
        """Plot the estimated velocity; its tracking error follows once its reference is known."""
        if self.inner is not None:
            self.inner.estimate(t_ns, eta, nu)
        self._error()
        self._at(t_ns)
        for k, (axis, _) in enumerate(AXES):
            self.rec.log(f"plots/velocity/{axis}/estimated", rr.Scalars(float(nu[k])))
        self._pending = (t_ns, np.array(nu, dtype=np.float64))

    def velocity_reference(self, t_ns: int, nu_ref: FloatArray) -> None:
        """Plot the commanded velocity."""
        if self.inner is not None:
            self.inner.velocity_reference(t_ns, nu_ref)
        if self._pending is not None and self._pending[0] < t_ns:
            self._error()  # an estimate before this reference is judged by the one before
        self._nu_ref = (t_ns, np.array(nu_ref, dtype=np.float64))
        self._at(t_ns)
        for k, (axis, _) in enumerate(AXES):
            self.rec.log(f"plots/velocity/{axis}/commanded", rr.Scalars(float(nu_ref[k])))

    def _error(self) -> None:
        """Plot the pending estimate's tracking error (the join of :mod:`hil.core.tracking`).

        The loop logs a tick's estimate before that tick's reference, so an
        estimate is judged when the next estimate or a later reference arrives.
        """
        pending, self._pending = self._pending, None
        if pending is None or self._nu_ref is None:
            return
        (t_ns, nu), (ref_t_ns, nu_ref) = pending, self._nu_ref
        joined = tracking_error(
            np.array([t_ns], dtype=np.int64), nu[None], np.array([ref_t_ns]), nu_ref[None]
        )
        if not len(joined):
            return
        self._at(t_ns)
        bound = np.full(3, np.nan)
        in_force = [d for d in self._decided if d[0] <= t_ns]
        decided_ns, cls = in_force[-1] if in_force else (t_ns, None)
        if cls is not None:
            since = np.array([(t_ns - decided_ns) / 1e9])
            bound = envelope_bound(self.scenario.transient, cls, since)[0]
        for k, (axis, _) in enumerate(AXES):
            error = float(joined.error[0, k])
            self.rec.log(f"plots/tracking_error/{axis}/error", rr.Scalars(error))
            band = [float(bound[k]), -float(bound[k])]
            self.rec.log(f"plots/tracking_error/{axis}/envelope", rr.Scalars(band))

    def force(self, t_ns: int, tau: FloatArray) -> None:
        """Plot the force demand."""
        if self.inner is not None:
            self.inner.force(t_ns, tau)
        self._at(t_ns)
        self.rec.log("plots/force", rr.Scalars(np.asarray(tau, dtype=np.float64)))

    def thrusters(self, command: ThrusterCommand) -> None:
        """Plot the thruster commands and azimuth angles."""
        if self.inner is not None:
            self.inner.thrusters(command)
        self._at(command.t_ns)
        self.rec.log(
            "plots/thrusters/commands",
            rr.Scalars([command.tunnel, command.port, command.starboard]),
        )
        angles = np.degrees([command.port_angle_rad, command.starboard_angle_rad])
        self.rec.log("plots/thrusters/azimuth_deg", rr.Scalars(angles))

    def decision(self, record: Decision) -> None:
        """Draw the safe inputs and the chosen one as arcs; plot the value."""
        if self.inner is not None:
            self.inner.decision(record)
        self._decided = [*self._decided[-1:], (record.t_ns, budget_class(record))]
        self._at(record.t_ns)
        safe, chosen = decision_strips(record, self.scenario.tau_s)
        self.rec.log("world/controller/safe_inputs", rr.LineStrips3D(safe))
        self.rec.log("world/controller/chosen_input", rr.LineStrips3D(chosen))
        self.rec.log("plots/value", rr.Scalars(finite_or_nan(record.value)))

    def obstacles(self, layout: ObstacleLayout) -> None:
        """Draw the real and inflated obstacles of a new layout."""
        if self.inner is not None:
            self.inner.obstacles(layout)
        self._at(layout.t_ns)
        real = tuple(
            rectangle_xy((r.x_min_m, r.x_max_m), (r.y_min_m, r.y_max_m)) for r in layout.obstacles
        )
        drawn = Layout(layout.t_ns, real, (), layout.obstacles)
        self.rec.log("world/arena/obstacles/real", rr.LineStrips3D([closed_strip(p) for p in real]))
        inflated = inflated_outlines(self.scenario, drawn)
        self.rec.log(
            "world/arena/obstacles/inflated", rr.LineStrips3D([closed_strip(p) for p in inflated])
        )
        self.rec.log(
            "world/arena/obstacles/names",
            rr.Points3D(
                [[*p.mean(axis=0), 0.0] for p in real],
                labels=obstacle_names(self.scenario, len(real)),
            ),
        )

    def event(self, t_ns: int, level: EventLevel, code: str, text: str) -> None:
        """Add a text log entry."""
        if self.inner is not None:
            self.inner.event(t_ns, level, code, text)
        self._at(t_ns)
        self.rec.log("events", rr.TextLog(f"{code}: {text}", level=LEVELS.get(level, "INFO")))

    def controller_ready(self, record: ControllerReady) -> None:
        """Plot the synthesis time of a controller put in force (full ones)."""
        if self.inner is not None:
            self.inner.controller_ready(record)
        if record.complete and math.isfinite(record.seconds):
            self._at(record.t_ns)
            self.rec.log("plots/synthesis_time_s", rr.Scalars(record.seconds))

    def close(self) -> None:
        """Flush what is buffered and detach from the sinks."""
        self._error()
        self.rec.flush()
        self.rec.disconnect()
