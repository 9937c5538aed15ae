"""Sub-commands of the `hil` command line (see :mod:`hil.cli`)."""

__all__: list[str] = []
