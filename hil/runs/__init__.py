"""Runs (layer 8): whole runs built on the runtime, and their summaries.

:mod:`hil.runs.sim_run` (a docking in simulation, recorded), :mod:`hil.runs.vessel_run`
(the stack on the vessel over ROS 2), :mod:`hil.runs.campaign` (Monte Carlo over starts),
:mod:`hil.runs.sweep` (grids and random samples over scenarios, seeds, starts, gains,
disturbances), the executor seam they run on (:mod:`hil.runs.executor` with the local
processes, :mod:`hil.runs.dask_executor`, chosen by :mod:`hil.runs.backends`), the
fan-out loop (:mod:`hil.runs.fanout`) and its results file (:mod:`hil.runs.results`),
:mod:`hil.runs.ros_vessel` (the simulated vessel as a ROS 2 node) and
:mod:`hil.runs.summary` (what a run achieved, judged on the true state). May import
every layer below (runtime, adapters, bag, sim, controllers, model, scenarios, core);
replay, views and commands build on it.
"""

__all__: list[str] = []
