"""Stability of the pipe: critical flow velocities, Argand/Campbell sweeps, stability maps
and Floquet analysis of pulsating flow or spin.  All quantities in SI units.
"""

from pipeflow.stability.core import REVERSE_FLOW_CAVEAT, eigenvalues, growth_rate, state_matrices
from pipeflow.stability.critical import CriticalVelocity, Crossing, critical_velocities

__all__ = [
    "REVERSE_FLOW_CAVEAT",
    "CriticalVelocity",
    "Crossing",
    "critical_velocities",
    "eigenvalues",
    "growth_rate",
    "state_matrices",
]
