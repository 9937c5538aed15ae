"""The control stack: symbolic (upper level), velocity PID, thrust allocation, observer."""

__all__: list[str] = []
