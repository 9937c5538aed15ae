"""Views (layer 10): Rerun recordings and plots of recorded runs, for people.

:mod:`hil.views.rerun_export` holds every Rerun call, :mod:`hil.views.plot` the
one-page matplotlib figure, :mod:`hil.views.controller_view` what both draw of the
symbolic controller (arcs, winning slices). May import every layer below, replay
included (a view can show replayed decisions beside the recorded ones); only the
commands import it.
"""

__all__: list[str] = []
