"""Views (layer 10): Rerun recordings and plots of recorded runs, for people.

Every Rerun call is in this package: :mod:`hil.views.rerun_export` writes a
recorded run to an ``.rrd`` or a viewer, from the per-stream loggers of
:mod:`hil.views.rerun_world` (arena frame) and :mod:`hil.views.rerun_plots` (time
series), with the shared look of :mod:`hil.views.rerun_style` and the layout of
:mod:`hil.views.blueprint`; :mod:`hil.views.rerun_live` streams a run as it goes.
:mod:`hil.views.plot` is the one-page matplotlib figure, :mod:`hil.views.controller_view`
what both draw of the symbolic controller (arcs, winning slices). May import every
layer below, replay included (a view can show replayed decisions beside the recorded
ones); only the commands import it.
"""

__all__: list[str] = []
