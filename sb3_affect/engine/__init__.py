"""The engine: many seeds of one agent in one call on the compiled kernel (``simulate``)."""

from sb3_affect.engine.simulation import simulate, simulate_columns

__all__ = ["simulate", "simulate_columns"]
