"""What a metered caller (:func:`pipeflow.parallel.metered`: the service's fast lane) is
charged before each part of a Magnus solve is paid: the estimated cost of its steps."""

from __future__ import annotations

from pipeflow.parallel import charge

#: estimated cost of one step of :func:`propagate` (its exponential, generator and share of
#: the products) on one core of the 2-core reference machine, fixed + per size^2.5 of the
#: exponent [s]: measured 5.0, 6.5, 12.5, 66, 190 and 362 us at sizes 6, 10, 20, 40, 60, 80
#: (the paper's example at 3-40 modes, 3,000 exponentials each; this gives 4.5, 6.0, 15.3,
#: 68, 180 and 365 us).  What :func:`~pipeflow.parallel.charge` is told before a propagation
STEP_FIXED_S = 4e-6
STEP_PER_SIZE25_S = 6.3e-9


def step_seconds(size: int) -> float:
    """Estimated run time of one Magnus step whose exponent is ``size`` x ``size`` [s]."""
    return STEP_FIXED_S + STEP_PER_SIZE25_S * size**2.5


def charge_steps(steps: float, size: int, what: str) -> None:
    """Charge ``steps`` Magnus steps of an exponent ``size`` x ``size`` (:func:`step_seconds`
    each) to a metered caller, saying ``what`` they are for."""
    charge(steps * step_seconds(size), what)
