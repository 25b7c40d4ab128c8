"""Errors raised while a simulation runs."""


class SimulationError(RuntimeError):
    """The simulation produced a state it cannot continue from (NaN or inf)."""
