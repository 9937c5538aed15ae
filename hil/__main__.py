"""Allow `python -m hil`."""

from hil.cli import main

raise SystemExit(main())
