"""Commands (layer 11): one module per `hil` sub-command (see :mod:`hil.cli`).

Each parses its arguments, calls the layers below (any of them) and turns every error
a user can cause into one line and an exit status; nothing imports it but the CLI.
"""

__all__: list[str] = []
