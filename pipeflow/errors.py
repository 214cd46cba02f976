"""Exceptions raised by pipeflow for input it cannot honour.

Every error names the offending input by the library's own parameter name
(``parameter``: ``"step"``, ``"t_end"``, ``"omega0"``, ``"modes"``...), never a JSON path:
the numerical modules know nothing of requests.  The schema layer, which turns a request
into library calls, maps that name onto the request field (``field``, a dotted path such as
``"options.step"``) with :meth:`PipeflowError.at`, so that the HTTP service can point at it.

A failure that ends a computation (or one case of a study) is described by an
:class:`ErrorRecord`, a neutral record (its kind, a slug, the field at fault, a message and
the data a reader needs), never by a web document: :func:`classify` is the one mapping from
exceptions to records; the HTTP service maps records to problem documents in one table.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from typing import Any


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

    def __reduce__(self) -> tuple[Any, ...]:
        # pickled whole (subclasses take other constructor arguments): an error raised by
        # a piece of a fan-out on another process reaches the caller with its parameter
        return (_rebuild, (type(self), self.message, dict(self.__dict__)))


def _rebuild(cls: type[PipeflowError], message: str, state: dict[str, Any]) -> PipeflowError:
    err = cls.__new__(cls)
    ValueError.__init__(err, message)
    err.__dict__.update(state)
    return err


class InvalidField(ValueError):
    """A request validator's refusal that names the offending field as data.

    ``loc``: the path of that field below the model (or field) the validator checks, as a
    tuple or a dotted path (``()``: the checked model itself); the message is the text
    shown as is.  Raised inside a pydantic validator, it reaches the
    ``ValidationError`` as a ``value_error`` whose ``ctx["error"]`` is this exception, so a
    reader takes the field from ``loc`` rather than from the message.
    """

    def __init__(self, message: str, loc: tuple[str | int, ...] | str | None = ()) -> None:
        super().__init__(message)
        self.message = message
        if isinstance(loc, str):
            loc = tuple(loc.split("."))
        self.loc: tuple[str | int, ...] = tuple(loc or ())

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.message, self.loc))


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


class OverAllowance(Exception):
    """Raised before metered work that would pass the allowance installed for it
    (:func:`pipeflow.parallel.metered`): the computation stops having paid only the work
    charged before, and its caller runs it again elsewhere (the service's fast lane hands
    the job to a worker).  Not a failure of the computation or of the request.

    ``spent_s`` [s]: estimated work charged so far; ``asked_s`` [s]: the work refused;
    ``bound_s`` [s]: the allowance; ``what``: the work refused (e.g. a magnus propagation
    of so many steps)."""

    def __init__(self, spent_s: float, asked_s: float, bound_s: float, what: str) -> None:
        super().__init__(
            f"{what} (estimated {asked_s * 1e3:.3g} ms after {spent_s * 1e3:.3g} ms) would pass "
            f"the allowance of {bound_s * 1e3:.3g} ms"
        )
        self.spent_s, self.asked_s, self.bound_s, self.what = spent_s, asked_s, bound_s, what


class StorageError(Exception):
    """A read or write of a store failed (disk full, I/O error, database unreachable): the
    service's result store, or a memo behind a fan-out.

    ``full`` is True when the cause is lack of space.  Nothing is wrong with the request:
    the same request succeeds once the store is writable again.
    """

    def __init__(self, message: str, *, full: bool = False) -> None:
        super().__init__(message)
        self.full = full


#: the kinds of :class:`ErrorRecord` (what a reader may rely on; the slug refines "refused")
RECORD_KINDS = ("refused", "numerical-range", "runtime-limit", "storage", "cancelled", "internal")


@dataclasses.dataclass(frozen=True)
class ErrorRecord:
    """Why a computation failed, with no web vocabulary (picklable, JSON-able).

    ``kind``: one of :data:`RECORD_KINDS`; ``type``: its slug (for ``refused``, the
    :attr:`PipeflowError.slug`, e.g. ``budget-exceeded``; else the kind itself);
    ``field``: dotted path of the request field at fault (None: no single field);
    ``message``: what went wrong, for a person; ``data``: what a reader needs besides
    (``parameter``, ``largest_stable_step``, ``smallest_step`` of a refusal; ``full`` of a
    storage failure; ``timeout_s`` and ``killed`` of a runtime limit; ``cause`` of a
    numerical-range failure).
    """

    kind: str
    type: str
    message: str
    field: str | None = None
    data: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The record as JSON (a job record's ``error`` column)."""
        return {
            "kind": self.kind,
            "type": self.type,
            "message": self.message,
            "field": self.field,
            "data": dict(self.data),
        }

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> ErrorRecord | None:
        """The record :meth:`to_dict` wrote; None for any other document (e.g. a job
        record written before records existed, which held the service's answer itself)."""
        if doc.get("kind") not in RECORD_KINDS or not isinstance(doc.get("message"), str):
            return None
        return cls(
            kind=str(doc["kind"]),
            type=str(doc.get("type") or doc["kind"]),
            message=doc["message"],
            field=doc.get("field"),
            data=dict(doc.get("data") or {}),
        )

    @classmethod
    def internal(cls, message: str) -> ErrorRecord:
        """A failure of the software, not of the request (``message`` as given)."""
        return cls("internal", "internal", message)

    @classmethod
    def runtime_limit(cls, timeout_s: float, *, killed: bool = False) -> ErrorRecord:
        """The computation ran past the runtime limit of ``timeout_s`` [s] (``killed``: it
        stopped reporting, so its process was restarted)."""
        how = " and stopped reporting, so its worker was restarted" if killed else ""
        return cls(
            "runtime-limit",
            "runtime-limit",
            f"the computation exceeded the runtime limit of {timeout_s:g} s{how}; ask for "
            "fewer modes, samples or a shorter t_end",
            data={"timeout_s": timeout_s, "killed": killed},
        )


def classify(exc: BaseException) -> ErrorRecord:
    """The one mapping from an exception that ended a computation to its record.

    - :class:`PipeflowError`: ``refused``, its slug, request field and message;
    - :class:`Cancelled`: ``cancelled`` (the reason given, or "cancelled");
    - ``ArithmeticError`` (overflow, division by zero) and ``LinAlgError``:
      ``numerical-range``: valid inputs whose magnitudes take the numerics out of double
      precision, which no single field can be blamed for;
    - :class:`StorageError`: ``storage`` (``data["full"]``);
    - anything else, pydantic's ``ValidationError`` included (requests arrive validated:
      one raised inside a computation is a bug): ``internal``.
    """
    from numpy.linalg import LinAlgError  # here: the client imports this module, not numpy

    if isinstance(exc, PipeflowError):
        data: dict[str, Any] = {"parameter": exc.parameter}
        if hasattr(exc, "largest_stable_step"):
            data["largest_stable_step"] = exc.largest_stable_step
        smallest = getattr(exc, "smallest_step", None)
        if smallest is not None:
            data["smallest_step"] = smallest
        return ErrorRecord("refused", exc.slug, exc.message, exc.field, data)
    if isinstance(exc, Cancelled):
        return ErrorRecord("cancelled", "cancelled", str(exc) or "cancelled")
    if isinstance(exc, ArithmeticError | LinAlgError):
        cause = f"{type(exc).__name__}: {exc}"
        return ErrorRecord(
            "numerical-range",
            "numerical-range",
            f"the inputs take the computation out of the range of double precision ({cause})",
            data={"cause": cause},
        )
    if isinstance(exc, StorageError):
        return ErrorRecord("storage", "storage", str(exc), data={"full": exc.full})
    return ErrorRecord.internal(f"internal error: {type(exc).__name__}: {exc}")
