"""Stability of the pipe: critical flow velocities, Argand/Campbell sweeps, stability maps
and Floquet analysis of pulsating flow or spin.  All quantities in SI units.

- :func:`critical_velocities`: every crossing of the stability boundary over a velocity range
- :func:`sweep`: eigenvalues against flow velocity (Argand) or spin (Campbell), tracked
- :func:`spin_map`, :func:`beta_map`: critical velocity against spin; u_cr(beta)
- :func:`floquet`, :func:`resonance_chart`: monodromy/multipliers; parametric resonance
"""

from pipeflow.model import REVERSE_FLOW_CAVEAT
from pipeflow.stability.core import eigenvalues, growth_rate, state_matrices
from pipeflow.stability.critical import CriticalVelocity, Crossing, critical_velocities
from pipeflow.stability.floquet import Floquet, ResonanceChart, floquet, resonance_chart
from pipeflow.stability.maps import BetaMap, SpinMap, beta_map, spin_map
from pipeflow.stability.sweeps import Sweep, sweep

__all__ = [
    "REVERSE_FLOW_CAVEAT",
    "BetaMap",
    "CriticalVelocity",
    "Crossing",
    "Floquet",
    "ResonanceChart",
    "SpinMap",
    "Sweep",
    "beta_map",
    "critical_velocities",
    "eigenvalues",
    "floquet",
    "growth_rate",
    "resonance_chart",
    "spin_map",
    "state_matrices",
    "sweep",
]
