"""Plausibility warnings (issue 34, item 8): a value far outside the pipe's own scales,
most likely sent in another unit than the field's SI one.

A spin of 3000 meant as rpm is 3000 rad/s, and the run diverges; nothing refuses it (a
request may well be out of the ordinary).  So a simulation's result warns, naming the
field, the value, the pipe's scale and the unit that would make the value ordinary:

- the spin: max |w0(t)| over the run above :data:`SPIN_FACTOR` times the first bending
  frequency of the pipe on its supports at rest, w1 = lambda_1^2 sqrt(EI / ((M1 + M2) L^4))
  [rad/s] (:attr:`pipeflow.model.Pipe.first_bending_frequency`; lambda_1 = 1.8751 for the
  cantilever);
- the flow: the flow number u = v L sqrt(M2 / EI) [-] of max |v(t)| above
  :data:`FLOW_FACTOR` times the pipe's critical flow number u_cr without spin (found by
  :func:`pipeflow.stability.critical_velocities`, 8 modes, searched only up to max |v| /
  :data:`FLOW_FACTOR`, and only when u could be that far past it: u > FLOW_FACTOR times
  :data:`U_CR_FLOOR`).

The unit suggested is, of a few usual ones (rpm and deg/s for a spin; ft/s, km/h, cm/s
and mm/s for a velocity), the one that reads the same number as the largest ordinary
value: below :data:`ORDINARY` times the scale (w1, v_cr); none if no such unit.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from pipeflow.errors import PipeflowError
from pipeflow.schema import units

if TYPE_CHECKING:
    from pipeflow.profiles import Profile
    from pipeflow.schema.simulation import SimulationSpec
    from pipeflow.simulation import Simulation

#: a spin above this many first bending frequencies is implausible [-]
SPIN_FACTOR = 10.0
#: a flow number above this many critical flow numbers is implausible [-]
FLOW_FACTOR = 10.0
#: u_cr of a cantilevered pipe without spin is above this for every mass ratio (4.4 at
#: beta = 0.05, rising with beta; Gregory & Paidoussis 1966): the search is skipped below
U_CR_FLOOR = 3.0
#: an ordinary value is below this many times its scale (w1, v_cr) [-]
ORDINARY = 2.0
#: units a number meant in them could have been sent as SI, by field
SPIN_UNITS = ("rpm", "deg/s")
VELOCITY_UNITS = ("ft/s", "km/h", "cm/s", "mm/s")
#: samples of a profile over the run for its max |value|
_SAMPLES = 2001


def _peak(profile: Profile, t_end: float) -> float:
    """max |p(t)| over [0, t_end] of a library profile (sampled)."""
    values = profile.value(np.linspace(0.0, t_end, _SAMPLES))
    return float(np.max(np.abs(values)))


def _suggestion(
    field: str, profile: Any, peak: float, si: str, candidates: tuple[str, ...], threshold: float
) -> str:
    """ "; if you meant rpm, send ..." for the usual unit that makes ``peak`` ordinary."""
    best: tuple[float, str] | None = None
    for unit in candidates:
        scale = units.conversion(unit, si)
        if isinstance(scale, str):
            continue
        value = peak * scale
        if value < threshold and (best is None or value > best[0]):
            best = (value, unit)
    if best is None:
        return ""
    value, unit = best
    if getattr(profile, "kind", None) == "constant":
        number = profile.value
        return (
            f"; if you meant {unit}, send {field}.value = "
            f'{{"value": {number:g}, "unit": "{unit}"}} ({value:.3g} {si})'
        )
    return (
        f'; if you meant {unit}, give the profile\'s numbers as {{"value": ..., "unit": '
        f'"{unit}"}} ({value:.3g} {si} at most)'
    )


def warnings(spec: SimulationSpec, sim: Simulation | None = None) -> list[str]:
    """The plausibility warnings of a simulation request (empty for ordinary values).

    ``sim``: the request's library arguments (:meth:`SimulationSpec.to_simulation`) when
    the caller has them already (the request is then not converted a second time)."""
    from pipeflow.stability.critical import critical_velocities

    if sim is None:
        sim = spec.to_simulation()
    out: list[str] = []
    p, t_end = spec.pipe, spec.time.t_end
    w1 = sim.pipe.first_bending_frequency
    spin = _peak(sim.spin, t_end)
    if spin > SPIN_FACTOR * w1:
        field = "rotation.omega0"
        out.append(
            f"{field} = {spin:.4g} rad/s is {spin / w1:.3g}x the pipe's first bending "
            f"frequency ({w1:.3g} rad/s)"
            + _suggestion(field, spec.rotation.omega0, spin, "rad/s", SPIN_UNITS, ORDINARY * w1)
        )
    velocity = _peak(sim.flow, t_end)
    if p.M2 > 0 and velocity > 0:
        pipe = sim.pipe
        u = float(pipe.flow_number(velocity))
        if u > FLOW_FACTOR * U_CR_FLOOR:
            try:
                found = critical_velocities(
                    pipe, 0.0, (0.0, velocity / FLOW_FACTOR), modes=8, points=61
                )
            except PipeflowError:  # a warning is no reason to fail the run
                return out
            v_cr, u_cr = found.critical_velocity, found.u_cr
            if v_cr is not None and u_cr is not None and u > FLOW_FACTOR * u_cr:
                field = "flow.velocity"
                out.append(
                    f"{field} = {velocity:.4g} m/s is u = {u:.3g}, {u / u_cr:.3g}x the pipe's "
                    f"critical flow number without spin (u_cr = {u_cr:.3g}, "
                    f"v_cr = {v_cr:.3g} m/s)"
                    + _suggestion(
                        field,
                        spec.flow.velocity,
                        velocity,
                        "m/s",
                        VELOCITY_UNITS,
                        ORDINARY * v_cr,
                    )
                )
    return out
