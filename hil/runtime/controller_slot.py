"""The controller in force and the obstacle report it relies on.

One slot per run: it takes every obstacle report in (recording it, renewing the report a
controller relies on when the shapes are the same, submitting a new layout or a timer's
re-synthesis), swaps in what the re-synthesis returns (an early controller is held until
it covers a decision, :meth:`ControllerSlot.take_early`), and says whether a decision may
rely on the report now (:meth:`ControllerSlot.fresh`). The loop (:mod:`hil.runtime.loop`)
keeps the modes, the reference in force and the decisions; the slot tells it what
happened (:class:`Swap`).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import replace

from hil.adapters.interfaces import ObstacleSource
from hil.core.arrays import FloatArray
from hil.core.records import ControllerReady, EventLevel
from hil.core.samples import ObstacleLayout
from hil.runtime.events import EventCode
from hil.runtime.protocols import RunLog, SymbolicController
from hil.runtime.report_age import ReportAgeBudget
from hil.runtime.resynthesis import Resynthesizer, SynthesisResult, VesselState
from hil.runtime.settings import NS_PER_S
from hil.runtime.stats import RunStats

__all__ = ["ControllerSlot", "Swap", "layout_covers"]

Event = Callable[[int, EventLevel, EventCode, str], None]
"""Records an event: (t ns, level, code, text)."""


class Swap(enum.Enum):
    """What a poll of the re-synthesis brought (:meth:`ControllerSlot.swap`)."""

    NOTHING = "nothing"
    """No result, or an early controller held for a later decision."""
    IN_FORCE = "in_force"
    """A full controller is in force now."""
    KEPT = "kept"
    """The synthesis failed; the controller in force still avoids the new layout."""
    LOST = "lost"
    """The synthesis failed and no controller is valid: the run must stop."""


def layout_covers(old: ObstacleLayout, new: ObstacleLayout) -> bool:
    """Whether every obstacle of `new` lies inside some obstacle of `old`.

    Then a controller synthesized for `old` avoids `new` as well and stays valid.
    """
    return all(
        any(
            o.x_min_m <= n.x_min_m
            and n.x_max_m <= o.x_max_m
            and o.y_min_m <= n.y_min_m
            and n.y_max_m <= o.y_max_m
            for o in old.obstacles
        )
        for n in new.obstacles
    )


class ControllerSlot:
    """The controller in force, its version and report, and the layouts submitted.

    Args:
        obstacles: Where obstacle reports come from.
        resynthesizer: Turns a layout into a controller (inline or in a thread).
        report_ages: The report age each controller is solved for (stated or measured).
        log: Every report taken in is recorded here.
        stats: The run's figures (syntheses, early controllers, report ages, stale stops).
        event: Records the slot's events.
        resynthesis_period_s: Re-synthesize the same layout this often; None: on change only.
        start_ns: The run's start: a report stamped before it (the scenario's) is recorded
            at the tick that first sees it.
    """

    def __init__(
        self,
        obstacles: ObstacleSource,
        resynthesizer: Resynthesizer[SymbolicController],
        report_ages: ReportAgeBudget,
        log: RunLog,
        stats: RunStats,
        event: Event,
        resynthesis_period_s: float | None,
        start_ns: int,
    ) -> None:
        self._obstacles = obstacles
        self.resynthesizer = resynthesizer
        """The worker that turns layouts into controllers (a test may put in its own)."""
        self._ages = report_ages
        self._log = log
        self._stats = stats
        self._event = event
        self._period_s = resynthesis_period_s
        self.start_ns = start_ns
        """The run's start (ns); the loop resets it when the run starts."""
        self.controller: SymbolicController | None = None
        """The controller in force (None before the first, or after a failed synthesis)."""
        self.version = 0
        """Its version (counts the syntheses submitted)."""
        self.layout: ObstacleLayout | None = None
        """The report the controller in force relies on (renewed by fresher reports)."""
        self.age_s = report_ages.stated_s
        """The report age the controller in force was solved for (s)."""
        self.in_force_early = False
        """The controller in force is an early one (a first decision waits for the full)."""
        self._early: SynthesisResult[SymbolicController] | None = None
        self._submitted: ObstacleLayout | None = None
        self._last_submit_ns: int | None = None
        self._stale = False

    def watch(
        self, t_ns: int, braking: bool, vessel: Callable[[], VesselState | None]
    ) -> None:
        """Take the newest obstacle report in: record, renew, or submit a synthesis.

        Args:
            t_ns: Now (ns).
            braking: The vessel is braking to rest: reports are recorded, nothing solved.
            vessel: The state an early controller must cover (None: wait for the full).
        """
        layout = self._obstacles.latest()
        submitted = self._submitted
        changed = submitted is None or layout.obstacles != submitted.obstacles
        # With obstacles that move, a controller is good for a bounded age of its report:
        # a fresher report of the same shapes renews that report's stamp (the one the
        # staleness check measures from) without a synthesis, the controller being the same.
        renewed = (
            not changed
            and self._ages.tracks
            and submitted is not None
            and layout.t_ns > submitted.t_ns
        )
        if (changed or renewed) and self._ages.tracks:
            self._ages.reported(layout.t_ns if layout.t_ns >= self.start_ns else t_ns)
        if changed or renewed:
            # Every report taken in is recorded, a renewal too: a replay re-runs the stack
            # on this stream and must see the report time each decision relied on. A
            # layout known before the run (the scenario's, stamped 0) is recorded when the
            # run first sees it, so that every topic of the log shares the run's clock.
            self._log.obstacles(
                layout if layout.t_ns >= self.start_ns else replace(layout, t_ns=t_ns)
            )
        if renewed:
            self._renew(layout, t_ns)
        period = self._period_s
        timer_due = (
            period is not None
            and self._last_submit_ns is not None
            and t_ns - self._last_submit_ns >= period * NS_PER_S
        )
        if not (changed or timer_due) or braking:
            return  # (braking to rest needs no new controller; reports are still recorded)
        if self.resynthesizer.busy and not changed:
            self._event(
                t_ns,
                EventLevel.WARN,
                EventCode.SYNTHESIS_OVERRUN,
                f"synthesis slower than {period} s; keeping controller v{self.version}",
            )
            self._last_submit_ns = t_ns
            return
        self._submitted = layout
        self._last_submit_ns = t_ns
        self.resynthesizer.submit(layout, self._ages.next_s(), vessel())

    def swap(self, t_ns: int) -> tuple[Swap, str]:
        """Take what the re-synthesis returned; return what happened and, if lost, why."""
        result = self.resynthesizer.poll()
        if result is None:
            return Swap.NOTHING, ""
        if result.controller is not None and not result.complete:
            self._early = result
            self._ready(result, result.controller, t_ns)
            return Swap.NOTHING, ""
        self._early = None
        self.in_force_early = False
        if result.controller is not None:
            self._put_in_force(result, t_ns)
            self._stats.resyntheses += 1
            self._stats.synthesis_seconds.append(result.seconds)
            self._ready(result, result.controller, t_ns)
            return Swap.IN_FORCE, ""
        self._stats.failed_syntheses += 1
        if self.layout is not None and layout_covers(self.layout, result.layout):
            self._event(
                t_ns,
                EventLevel.WARN,
                EventCode.SYNTHESIS_FAILED,
                f"{result.error}; keeping controller v{self.version}, "
                "which still avoids the new layout",
            )
            return Swap.KEPT, ""
        self.controller = None
        self._event(
            t_ns,
            EventLevel.ERROR,
            EventCode.SYNTHESIS_FAILED,
            f"{result.error}; no valid controller, stopping the vessel",
        )
        return Swap.LOST, f"synthesis failed ({result.error}); no controller to go on with"

    def _ready(
        self, result: SynthesisResult[SymbolicController], controller: SymbolicController,
        t_ns: int,
    ) -> None:
        """Record a controller taken: its fields, and the event that says it in words."""
        record = ControllerReady(
            t_ns, result.version, result.seconds, controller.source, result.complete,
            result.report_age_s, result.layout.t_ns,
        )  # fmt: skip
        self._log.controller_ready(record)
        self._event(t_ns, EventLevel.DEBUG, EventCode.CONTROLLER_READY, record.describe())

    def take_early(self, t_ns: int, eta_hat: FloatArray, reference: int | None) -> None:
        """Put the early controller in force when it covers this (non-first) decision.

        `reference`: the input in force, None when the decision is a first one. The early
        controller then answers exactly as the full one will: the state's value is at
        most the level it was solved to, so every successor it relies on is final.
        """
        early = self._early
        if early is None or early.controller is None or reference is None:
            return
        if math.isinf(early.controller.value(eta_hat, reference, False)):
            return
        self._early = None
        self.in_force_early = True
        self._put_in_force(early, t_ns)
        self._stats.early_controllers += 1

    def fresh(self, t_ns: int) -> bool:
        """Return whether a decision may rely on the controller's obstacle report now.

        With obstacles that move, the synthesis avoided where they may be up to A + tau
        + late after their report (A: the report age the controller was solved for); a
        decision later than A after it is not covered: ``obstacles_stale`` (once per
        episode) and False, until a fresher report is in (renewing the controller's
        stamp, or its shapes' controller synthesized): ``obstacles_back``.
        """
        layout = self.layout
        if not self._ages.tracks or layout is None or self.controller is None:
            return True
        age_s = (t_ns - layout.t_ns) / NS_PER_S
        if age_s <= self.age_s:
            if self._stale:
                self._stale = False
                self._event(
                    t_ns,
                    EventLevel.INFO,
                    EventCode.OBSTACLES_BACK,
                    f"obstacle report {age_s:.2f} s old; deciding again",
                )
            return True
        if not self._stale:
            self._stale = True
            self._stats.obstacle_stale_stops += 1
            self._event(
                t_ns,
                EventLevel.ERROR,
                EventCode.OBSTACLES_STALE,
                f"obstacle report of t={layout.t_ns} ns is {age_s:.2f} s old (max "
                f"{self.age_s:g} s): velocity reference zero until a fresher one",
            )
        return False

    def _put_in_force(self, result: SynthesisResult[SymbolicController], t_ns: int) -> None:
        self.controller = result.controller
        self.version = result.version
        # A fresher report of the same shapes may have come in while it was solved:
        # the controller relies on the newest (renewed) one.
        self._rely_on(self._renewed(result.layout), result.report_age_s, t_ns, result.layout)
        self._warn_if_stale_on_arrival(t_ns, result.version, result.seconds)

    def _renew(self, layout: ObstacleLayout, t_ns: int) -> None:
        """Take a fresher report of the submitted shapes as the newest, without synthesis.

        The controller in force, when synthesized for the same shapes, now relies on this
        report: its age is measured from `layout`'s stamp. A synthesis of these shapes
        still running finishes with the renewed stamp (:meth:`_renewed`).
        """
        self._submitted = layout
        current = self.layout
        if current is not None and current.obstacles == layout.obstacles:
            self._rely_on(layout, self.age_s, t_ns)

    def _rely_on(
        self,
        layout: ObstacleLayout,
        report_age_s: float,
        t_ns: int,
        solved: ObstacleLayout | None = None,
    ) -> None:
        """Let decisions rely on `layout`'s report (solved for `report_age_s`) from `t_ns` on.

        `solved`: the report a controller put in force now was solved from (`layout` is
        a renewal of it, or itself); None for a renewal of the controller in force. The
        latency of a controller put in force and the age the report relied on so far had
        when this fresher one took over are what a measured report age is made of
        (:class:`ReportAgeBudget`).
        """
        current = self.layout
        if solved is not None and (current is None or solved.obstacles != current.obstacles):
            # Only a new layout's latency counts: the same shapes again (a timer's
            # re-synthesis) are renewed by every report, whatever their solve took.
            self._ages.in_force(solved.t_ns, t_ns)
        if current is not None and layout.t_ns > current.t_ns:
            self._ages.superseded(current.t_ns, t_ns)
        self.layout = layout
        self.age_s = report_age_s
        if self._ages.tracks:
            s = self._stats
            s.report_age_relied_s = self._ages.largest_age_s
            s.report_age_solved_s = max(s.report_age_solved_s, report_age_s)

    def _renewed(self, layout: ObstacleLayout) -> ObstacleLayout:
        """Return the newest report of `layout`'s shapes (a renewal while it was solved)."""
        submitted = self._submitted
        if (
            submitted is not None
            and submitted.obstacles == layout.obstacles
            and submitted.t_ns > layout.t_ns
        ):
            return submitted
        return layout

    def _warn_if_stale_on_arrival(self, t_ns: int, version: int, seconds: float) -> None:
        """Say when a controller for moving obstacles arrives older than its report may be.

        Its decisions would all be refused (``obstacles_stale``) unless a fresher report
        of the same shapes renews it: with obstacles that keep moving, a synthesis slower
        than the report age it was solved for never yields a usable controller.
        """
        layout = self.layout
        if not self._ages.tracks or layout is None:
            return
        age_s = (t_ns - layout.t_ns) / NS_PER_S
        if age_s <= self.age_s:
            return
        remedy = (
            "the next layouts are solved for the age measured "
            f"(now {self._ages.next_s():g} s)"
            if self._ages.measured
            else 'with obstacles that keep moving, set [obstacle_motion] report_age = "measured" '
            "(or raise max_report_age_s above the synthesis time), or give the synthesis "
            "more cores ([loop] synthesis_threads)"
        )
        self._event(
            t_ns,
            EventLevel.WARN,
            EventCode.SYNTHESIS_OVERRUN,
            f"controller v{version} arrived {age_s:.2f} s after its obstacle report "
            f"(synthesis {seconds:.2f} s), older than the {self.age_s:g} s it was solved for: "
            f"usable only once a fresher report of the same shapes renews it; {remedy}",
        )
