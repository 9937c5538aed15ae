"""Adapters: interfaces (typing.Protocol) and backends (sim, log, ros) for the world."""

__all__: list[str] = []
