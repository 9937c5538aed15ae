"""The closed set of runtime events; each has one defined behaviour."""

from __future__ import annotations

import enum


class EventCode(enum.Enum):
    """Closed set of runtime events, each with a defined behaviour."""

    CONTROLLER_READY = "controller_ready"
    """A (re-)synthesized controller was swapped in."""
    SYNTHESIS_FAILED = "synthesis_failed"
    """No controller for the new layout: the previous one is kept if still valid, else stop."""
    SYNTHESIS_OVERRUN = "synthesis_overrun"
    """Synthesis slower than its period: the last controller stays in charge. Also (WARN)
    a controller for moving obstacles that arrived older than ``max_report_age_s`` after
    its report (the text gives both times): it is swapped in, and decisions wait for a
    fresher report of the same shapes to renew it (``obstacles_stale`` until then)."""
    NOT_WINNING = "not_winning"
    """The estimate is outside the winning set and the safety set: the vessel is stopped
    (nu_ref = 0); the run is aborted at the run's first decision, or when the next
    decision is still not winning."""
    DOCKING_LOST = "docking_lost"
    """Docking is not winning from the estimate (a moving obstacle closed the passage), but
    the vessel can stay safe (WARN, once per episode): the safety controller's inputs
    are flown, the slowest first, until docking wins again."""
    DOCKING_BACK = "docking_back"
    """Docking is winning again after a wait on the safety controller: docking resumes."""
    NO_CONTROLLER = "no_controller"
    """No valid controller: the vessel is stopped (nu_ref = 0)."""
    POSE_LOST = "pose_lost"
    """Pose stale beyond the timeout: thrusters to zero until it is back."""
    POSE_BACK = "pose_back"
    """Pose fresh again: control resumes."""
    OBSTACLES_STALE = "obstacles_stale"
    """A decision was due while the obstacle report its controller was synthesized from
    was older than the scenario's ``max_report_age_s`` (only with obstacles that move;
    ERROR; the text gives the age): the synthesis covered their motion only that long,
    so no decision is taken, the velocity reference goes to zero and the next decision
    after a fresher report (of the same shapes: the controller's stamp renewed; moved: its
    controller synthesized) is a first decision."""
    OBSTACLES_BACK = "obstacles_back"
    """A controller from a fresh enough obstacle report is in force again: decisions resume."""
    SAMPLE_REJECTED = "sample_rejected"
    """A sample was refused (non-finite, out of range, out of order, gated)."""
    THRUSTER_FAILURE = "thruster_failure"
    """A thruster command could not be delivered."""
    TARGET_REACHED = "target_reached"
    """The estimate entered the target set: holding position."""
    DOCKED = "docked"
    """The vessel held the target for the required time: the run ends."""
    TIMEOUT = "timeout"
    """The run's time limit passed before docking."""
    STOPPED = "stopped"
    """The run was stopped (signal, fatal fault)."""
    TUBE_EXIT = "tube_exit"
    """The estimate left the current decision's tube cells by more than the estimation
    bound (ERROR; the text gives the distance in m and the decision's time): the
    guarantee no longer covers the interval, so a new decision is taken at once as a
    first decision (reference in force: the input nearest the estimated velocity); it
    finds a safe input or stops the vessel as NOT_WINNING does."""
    SUCCESSOR_MISS = "successor_miss"
    """At the next decision the estimate was outside the previous decision's successor
    cells (WARN; distance in m and heading angle in rad): the decision is taken from the
    cell the vessel is in, as always."""
    VALUE_NOT_DECREASING = "value_not_decreasing"
    """At the next decision the value (previous input in force) was not below the
    previous decision's (WARN; both values): the decision is taken as always."""
    AT_REST = "at_rest"
    """Braking after a stop ended (INFO at rest, WARN when not at rest after the longest
    braking): thrusters to zero."""
    LATE_INTERVAL = "late_interval"
    """A decision came later than tau + the late budget after the previous one (ERROR,
    with how long the input was held and by how much too long): the loop stalled, and the
    one-step budget, bounded over periods up to tau + late, does not cover that interval.
    The decision is taken at once, as a first decision (from the estimated velocity)."""
    POSE_FEED_PREMISE = "pose_feed_premise"
    """The pose feed is slower than the premise in force (vessel config ``pose_feed``):
    ``hil vessel`` refuses to start on it (ERROR, the measured rate and the premise)."""
    ESTIMATE_INCONSISTENT = "estimate_inconsistent"
    """The EKF's innovations broke its noise model over a window of poses (ERROR, with
    the mean NIS, the share of gated poses and the RMS position innovation against
    their limits, :mod:`hil.controllers.consistency`): the estimation bound the
    guarantee assumes is no longer credible, so the run is aborted with a safe stop
    (braking to rest on the estimate, the best the loop has)."""
    TELEMETRY_FAILED = "telemetry_failed"
    """A live telemetry message of ``hil vessel`` could not be published (WARN, once per
    topic, :mod:`hil.adapters.ros_telemetry`): the run goes on, its log keeps everything."""
    ABORTED = "aborted"
    """The run cannot go on (no controller for the layout, a state no safe input leaves
    from): thrusters to zero and the run ends at once, the text saying why."""
