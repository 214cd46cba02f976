"""Exceptions raised by pipeflow for input it cannot honour.

Every error names the offending input by the library's own parameter name
(``parameter``: ``"step"``, ``"t_end"``, ``"omega0"``, ``"modes"``...), never a JSON path:
the numerical modules know nothing of requests.  The schema layer, which turns a request
into library calls, maps that name onto the request field (``field``, a dotted path such as
``"options.step"``) with :meth:`PipeflowError.at`, so that the HTTP service can point at it.
"""

from __future__ import annotations

import re


class PipeflowError(ValueError):
    """Base class: a request pipeflow refuses, with the parameter it concerns.

    ``parameter``: the library's name of the offending argument (None if none applies);
    ``field``: the request field it came from, set by the schema layer (None until then).
    """

    def __init__(self, message: str, parameter: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.parameter = parameter
        self.field: str | None = None

    @property
    def slug(self) -> str:
        """The kind of refusal as a problem type: ``BudgetExceeded`` -> ``budget-exceeded``."""
        return re.sub(r"(?<!^)(?=[A-Z])", "-", type(self).__name__).lower()

    def at(self, field: str | None) -> PipeflowError:
        """Record the request field this error concerns (the schema layer's mapping)."""
        self.field = field
        return self


class InvalidInput(PipeflowError):
    """An input value is out of range or inconsistent with another."""


class UnstableStep(PipeflowError):
    """A user-given explicit time step lies outside the method's stability region."""

    def __init__(self, message: str, parameter: str | None, largest_stable_step: float) -> None:
        super().__init__(message, parameter)
        self.largest_stable_step = largest_stable_step


class BudgetExceeded(PipeflowError):
    """A run would cost more (steps, evaluations, memory) than the configured budget.

    ``smallest_step`` [s]: when the step is what exceeds the budget, the smallest step the
    budget allows (None otherwise).
    """

    def __init__(
        self, message: str, parameter: str | None = None, smallest_step: float | None = None
    ) -> None:
        super().__init__(message, parameter)
        self.smallest_step = smallest_step


class Cancelled(Exception):
    """Raised inside a solver when its progress callback asks it to stop."""
