"""Magnus propagation of orders 4 and 6: the paper's CMA applied on short intervals.

On each step [t, t + h] the propagator of z' = S(t) z + f(t) is exp(Omega) with a
Gauss-Legendre Magnus generator (Blanes, Casas, Oteo & Ros, Physics Reports 470 (2009),
section 5.2; Blanes, Casas & Ros, BIT 40 (2000) 434-450):

- order 4, two nodes A_1, A_2 = A(t + (1/2 -+ sqrt(3)/6) h)::

      Omega4 = h/2 (A_1 + A_2) + sqrt(3) h^2 / 12 [A_2, A_1]              (one commutator)

- order 6, three nodes A_1, A_2, A_3 = A(t + (1/2 - sqrt(15)/10, 1/2, 1/2 + sqrt(15)/10) h)::

      a1 = h A_2,  a2 = sqrt(15) h / 3 (A_3 - A_1),  a3 = 10 h / 3 (A_3 - 2 A_2 + A_1)
      C1 = [a1, a2],  C2 = -1/60 [a1, 2 a3 + C1]
      Omega6 = a1 + a3 / 12 + 1/240 [-20 a1 - a3 + C1, a2 + C2]           (three commutators)

which are O(h^5) and O(h^7) locally.  Without external loads ``A`` is the state matrix
augmented with the forcing of a varying spin: the state is extended by a constant c
(= |z0|), so the affine system becomes the linear one (z, c)' = [[S, f/c], [0, 0]] (z, c)
and the same exponential carries the Duhamel term.  With external loads the forcing is not
put in that border column (its commutators carry A (f(t_2) - f(t_1)), of size
h |xi_max| h |f'|, which made the steps follow h |xi_max| instead of the physics: 20-80x
the unforced steps): each step is an exponential-integrator step (:func:`forced_omega`),
the total forcing interpolated by a polynomial at Gauss nodes and the polynomial's
monomials added to the state as a nilpotent Jordan block, whose bordered Magnus generator
[[Omega, Y], [0, J]] sees the forcing only through A's variation; one exponential of size
N + 4 (order 4) per step, cut to the affine step [[P, r], [0, 1]].  At constant
coefficients, loads that are sums of exponential-polynomial terms (constants, polynomials,
harmonics) are instead the states of their own linear system (:mod:`.states`: at most 4,
in place of the Jordan block): the forcing is then exact and so is each step.  For constant
coefficients Omega = h S exactly, so the method is exact to rounding (one exponential for a
uniform output grid).

Order per interval.  At :data:`LOCAL_SAMPLES` times the local errors of one step of each
order are compared by step doubling (|E_h - E_h/2 E_h/2|_1 / (1 - 2^-p) for order p), but
only where h |A|_1 <= :data:`ORDER6_NORM`: order 6 is used around a sample where its local
error is below 1/:data:`ORDER6_GAIN` of order 4's, order 4 elsewhere.  While h |xi_max| >> 1
(the paper's 10 modes at 2001 samples: h |A|_1 ~ 42) the Magnus series has not converged,
order 6's extra terms are larger than order 4's error (its local error is ~20x order 4's
there) and order 4 is used; with few modes or tight tolerances order 6 takes over where the
coefficients vary fast.

Error estimate and step control (``Options.tolerance``, relative global error of the
state).  The run is compared with one of twice the step on every other output time (the
same orders): estimate = max_k |Z_h(t_k) - Z_2h(t_k)| / max_k |Z_h(t_k)| / 4, conservative
for order 4 (ratio err(2h)/err(h) = 16) and more so for order 6; while h |xi_max| > pi the
observed ratio is 5-15 and the estimate is within a factor ~2.  Above the tolerance, every
interval's sub-step count is multiplied by (estimate / (SAFETY tolerance))^(1/rate), with
the rate log2(d2/d1) observed against a third run with four times the step (clipped to
[log2 5, order]): not halving over the whole run, and not the h^4 law where the error falls
slower (h |xi_max| > pi) or faster (the transition to the asymptotic regime); and by at
most :data:`MAX_REFINEMENT` = 8 at once (an estimate far outside the asymptotic regime
asks for too much: a 3,000 rad/s force on the paper example asked 67x, 134,000 steps for a
true 7e-13, where 16,000 meet the tolerance; the supported pipe of benchmarks/bench_supports
15x).  A refined
attempt is checked against the previous attempt (no fresh run with twice the step): the
difference over ratio^2 - 1 (:data:`REFINED_FLOOR_RATE`: the error of a refinement is
assumed to fall at least like h^2; with log2 5, the first check's rate, the paper example
forced from rest reported 6.9e-9 for a true 7.2e-9).  Pulsating flow v = 2 + sin 50 t on the
paper example: 33,500 exponentials before, 23,500 now, for the same 20,000 steps.  Local
error control proper (per-step estimates) was tried and measured: on these oscillatory
systems the local errors of successive steps cancel, so their sum over-predicts the global
error ~50x (v = 0.4 t, 2001 steps: local 2e-10 per step, global 7e-9) and over-resolves
more than the global comparison does.

A step never crosses a time the control runs on.  On a sparse output grid those are the
output times: reaching an output inside a longer step would cost one exponential (of the
partial step) anyway, so the run takes at least one step per output interval.

Dense output (a uniform grid of more than :data:`DENSE_STEPS` intervals, no user step,
coefficients varying in time): the steps are decoupled from the samples.  The control runs
on a coarse subset of the output times (:func:`dense_selection`: every m-th sample and the
last, coarse intervals of at most min(pilot step, t_end / DENSE_STEPS), the step the
paper's 2,001-sample example meets 1e-8 with at its first attempt); a refinement splits
coarse intervals at samples (:func:`dense_refine`) instead of adding sub-steps, so a coarse
interval that spans several samples is always one Magnus step.  The samples inside are
then filled from the coarse state at its left end (:func:`dense_fill`), never accumulated
across coarse intervals: sample to sample by Magnus-4 steps of the sample spacing d, whose
propagator varies smoothly with the sample index j, so it is taken as a polynomial in j
through exact exponentials of sample steps at nodes (linear: the steps centred on the
two coarse times, each shared by two coarse intervals) and each sample costs two
matrix-vector products, batched over the coarse intervals; the neglected terms are second
order in the exponent's variation over the interval.  The fill's own error is measured on
about :data:`LOCAL_SAMPLES` coarse intervals against a march of exact sixth-order Magnus
exponentials of the sample steps and added to the estimate; where it exceeds
:data:`FILL_SHARE` of the tolerance (or what the coarse estimate leaves of it) the fill is
redone with a quadratic polynomial, then with one exact exponential per sample (a low-norm
one), batched over the coarse intervals.  A checkpoint (:class:`MagnusCheckpoints`) holds
the control's propagations on the coarse times; a resumed run fills again after them (the
fill is not checkpointed: a fraction of the run, with no long sequential chain).

All exponentials of a block of steps are computed at once
(:func:`~pipeflow.linalg.expm_stack`, scaling and squaring of a Taylor polynomial with
batched matrix products); only the final propagation is sequential, one matrix-vector
product per output interval: interval k gets m_k equal sub-steps, and their exponentials
are multiplied together (batched, pairwise: :func:`~pipeflow.linalg.product_of_steps`)
before they touch the state.

The building blocks (:data:`~pipeflow.linalg.GAUSS_NODES`,
:func:`~pipeflow.linalg.magnus4_omega`, :func:`~pipeflow.linalg.magnus6_omega`,
:func:`~pipeflow.linalg.expm_stack`, :func:`~pipeflow.linalg.product_of_steps`) live in
:mod:`pipeflow.linalg`, shared with the Floquet analysis (:mod:`pipeflow.stability.floquet`),
which propagates Z' = S(t) Z over a period.

The package by concern: :mod:`~pipeflow.solvers.magnus.generator` (the Magnus generators,
the order choice and the step plan), :mod:`~pipeflow.solvers.magnus.stepper` (one
propagation, :func:`propagate`), :mod:`~pipeflow.solvers.magnus.control` (the solver
:class:`Magnus` and its step control, :func:`step_control`),
:mod:`~pipeflow.solvers.magnus.dense` (dense output, an object: :class:`DenseOutput`),
:mod:`~pipeflow.solvers.magnus.checkpoints` (:class:`MagnusCheckpoints`),
:mod:`~pipeflow.solvers.magnus.metering` (what a metered caller is charged) and
:mod:`~pipeflow.solvers.magnus.stack` (many problems at once, :func:`solve_many`).
"""

from pipeflow.solvers.magnus.checkpoints import MagnusCheckpoints as MagnusCheckpoints
from pipeflow.solvers.magnus.control import MAX_ATTEMPTS as MAX_ATTEMPTS
from pipeflow.solvers.magnus.control import MAX_REFINEMENT as MAX_REFINEMENT
from pipeflow.solvers.magnus.control import PILOT_STEPS as PILOT_STEPS
from pipeflow.solvers.magnus.control import REFINED_FLOOR_RATE as REFINED_FLOOR_RATE
from pipeflow.solvers.magnus.control import RICHARDSON_DIVISOR as RICHARDSON_DIVISOR
from pipeflow.solvers.magnus.control import ROUNDING_PER_STEP as ROUNDING_PER_STEP
from pipeflow.solvers.magnus.control import SAFETY as SAFETY
from pipeflow.solvers.magnus.control import Magnus as Magnus
from pipeflow.solvers.magnus.control import MagnusRun as MagnusRun
from pipeflow.solvers.magnus.control import StepControl as StepControl
from pipeflow.solvers.magnus.control import step_control as step_control
from pipeflow.solvers.magnus.dense import DENSE_STEPS as DENSE_STEPS
from pipeflow.solvers.magnus.dense import FILL_MARGIN as FILL_MARGIN
from pipeflow.solvers.magnus.dense import FILL_SHARE as FILL_SHARE
from pipeflow.solvers.magnus.dense import DenseFill as DenseFill
from pipeflow.solvers.magnus.dense import DenseOutput as DenseOutput
from pipeflow.solvers.magnus.dense import dense_fill as dense_fill
from pipeflow.solvers.magnus.dense import dense_refine as dense_refine
from pipeflow.solvers.magnus.dense import dense_selection as dense_selection
from pipeflow.solvers.magnus.generator import LOCAL_SAMPLES as LOCAL_SAMPLES
from pipeflow.solvers.magnus.generator import MagnusGenerator as MagnusGenerator
from pipeflow.solvers.magnus.generator import StepPlan as StepPlan
from pipeflow.solvers.magnus.generator import augmented_initial_state as augmented_initial_state
from pipeflow.solvers.magnus.generator import choose_orders as choose_orders
from pipeflow.solvers.magnus.generator import forced_omega as forced_omega
from pipeflow.solvers.magnus.generator import load_scale as load_scale
from pipeflow.solvers.magnus.metering import STEP_FIXED_S as STEP_FIXED_S
from pipeflow.solvers.magnus.metering import STEP_PER_SIZE25_S as STEP_PER_SIZE25_S
from pipeflow.solvers.magnus.metering import step_seconds as step_seconds
from pipeflow.solvers.magnus.stepper import propagate as propagate
