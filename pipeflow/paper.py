"""The paper's cases, defined once (Wang & Zhong 2018, section 5).

The worked example is the pipe :data:`PAPER_PIPE` spinning at w0 = :data:`PAPER_OMEGA0`
rad/s with the flow v = 0.4 t m/s (:data:`PAPER_FLOW`), u0 = 1 mm, 10 modes over 1 s at 2001
samples; the paper's other flow cases (a = 0.4 m/s constant, linear and quadratic in t, and
reversed) are :data:`PAPER_FLOWS`.  The request schemas build their JSON example from these
values (:data:`pipeflow.schema.simulation.PAPER_EXAMPLE`); tests and benchmarks use them.
"""

from __future__ import annotations

from typing import Any

from pipeflow.model import Pipe
from pipeflow.profiles import Constant, Polynomial, Profile, polynomial

#: the worked example's pipe (the cross-section A = 1.57e-8 m^2 is not needed by the model)
PAPER_PIPE = Pipe(E=7.8e9, I=1.21e-17, L=0.025, M1=1.884e-5, M2=1.6485e-5)
#: its fields as JSON (the ``pipe`` of the request examples)
PAPER_PIPE_JSON: dict[str, Any] = {
    name: getattr(PAPER_PIPE, name) for name in ("E", "I", "L", "M1", "M2")
}

#: spin of every case w0 [rad/s]
PAPER_OMEGA0 = 100.0
PAPER_SPIN = Constant(PAPER_OMEGA0)
#: flow amplitude a [m/s] of the flow cases
PAPER_A = 0.4
#: the example's flow v = a t [m/s]
PAPER_FLOW: Polynomial = polynomial(0, PAPER_A)
#: the paper's flow cases v(t) [m/s] by name
PAPER_FLOWS: dict[str, Profile] = {
    "v=0.4": Constant(PAPER_A),
    "v=0.4t": PAPER_FLOW,
    "v=0.4t^2": polynomial(0, 0, PAPER_A),
    "v=-0.4": Constant(-PAPER_A),
    "v=-0.4t": polynomial(0, -PAPER_A),
}

#: the example's initial amplitude u0 [m] (shape phi_1 of eq. 3), modes, duration [s], samples
PAPER_U0 = 0.001
PAPER_MODES = 10
PAPER_T_END = 1.0
PAPER_SAMPLES = 2001
