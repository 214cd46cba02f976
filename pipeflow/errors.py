"""Exceptions raised by pipeflow for input it cannot honour.

Every error names the offending input (``field``, a dotted path such as
``"options.step"``) so that a caller, or the HTTP service, can point at it.
"""

from __future__ import annotations


class PipeflowError(ValueError):
    """Base class: a request pipeflow refuses, with the field it concerns."""

    def __init__(self, message: str, field: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.field = field


class InvalidInput(PipeflowError):
    """An input value is out of range or inconsistent with another."""


class UnstableStep(PipeflowError):
    """A user-given explicit time step lies outside the method's stability region."""

    def __init__(self, message: str, field: str | None, largest_stable_step: float) -> None:
        super().__init__(message, field)
        self.largest_stable_step = largest_stable_step


class BudgetExceeded(PipeflowError):
    """A run would cost more (steps, evaluations, memory) than the configured budget."""


class Cancelled(Exception):
    """Raised inside a solver when its progress callback asks it to stop."""
