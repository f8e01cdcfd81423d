"""A saturated machine's flux map ``psi_d(i_d, i_q)``, ``psi_q(i_d, i_q)`` (and R, and the inverter voltage
error) from a drive log at speed (``pmsmjax identify --flux-map``).

**The equations: the voltage equation in integral form.** In the rotor frame
``u = R i + dpsi(i)/dt + w_e J psi(i)`` (``J = [[0, -1], [1, 0]]``; the book, ch. 1, with ``psi`` the
flux map instead of ``L i + psi_f``). Integrated over a short window ``[t_a, t_b]`` of the log it needs no
derivative of the noisy current:

``psi(i_b) - psi(i_a) + int (R i + w_e J psi(i) + V_e e(i, theta)) dt = int u dt``,

``e`` the dq voltage an error of one volt per phase (dead time, device drop: ``tanh(i_x / eps)`` of each
phase current, as [`tuning.identify.electrical`][tuning.identify.electrical]) takes away. The voltage's
integral is exact for the hold the log records (stator-frame hold: the dq voltage turns by ``-w_e (t - t_k)``
over the interval); the others are trapezoidal sums of the samples. Windows start at every ``stride``-th
sample, so transients contribute both through ``psi(i_b) - psi(i_a)`` (the incremental inductances along the
path) and through ``w_e J psi(i)`` (the flux itself wherever the current passed), not only the steady points;
windows do not span a reversal of the speed (an interval whose speed changes by more than
[`SPEED_JUMP`][tuning.identify.flux_map_fit.SPEED_JUMP] of the log's top speed).

**Each window's ends are averaged** over [`ENDPOINT_SAMPLES`][tuning.identify.flux_map_fit.ENDPOINT_SAMPLES]
samples (the equation is the mean of that many windows, each a sample later). The map is evaluated at the
measured, noisy currents: at a dwell, windows whose ends differ only by the current noise ``di`` say
``L di ~ 0``, and so many of them pull the incremental inductance towards zero (regression towards the
mean with noisy regressors). Averaged ends divide that noise's variance by the samples averaged while
keeping a transient's change; measured on the reluctance machine's staircase it halves the map's error.

**The unknowns.** ``psi`` is the bicubic Hermite interpolant of node fluxes on a uniform grid over the
visited currents
([`pmsmjax.machines.flux_map.hermite_coefficients`][pmsmjax.machines.flux_map.hermite_coefficients], the
interpolant every command uses), so the identified map is exactly what the plant will run. The interpolant is
linear in the node fluxes, and the equations are linear in ``(node fluxes, R, V_e)``: the least-squares
problem is linear. Its Jacobian is taken by JAX (forward mode through ``hermite_coefficients``, exact for a
linear map), and one Gauss-Newton step (a dense least-squares solve) is its exact minimum. Only the width
``eps`` of the inverter error's sign enters nonlinearly: unless given it is found by a bounded scalar search
of that linear solve's residual (`_profiled_smoothing`).

**Separability.** Steady state at ``+w_e`` and ``-w_e`` gives ``u = R i +- w_e J psi``: R from the sum,
the flux from the difference. A log at one direction of rotation only does not separate R from ``psi``
(R is then required, ``--fix R=...``). ``V_e`` separates from R because it is not proportional to the
current (it is ``~ 4/pi V_e`` in the current's direction whatever the current's size).

**The grid** ([`grid_step`][tuning.identify.flux_map_fit.grid_step] unless ``step_a`` is given): the
finest 1-2-2.5-5 step at which most visited places have a densely sampled node nearby, snapped to multiples
of the step over the visited currents, ending at the last rows and columns the log reaches.

**The d-axis symmetry (default).** A rotor symmetric about its d axis (the magnet's axis: every standard
surface-magnet, interior-magnet and (PM-assisted) reluctance rotor) links ``psi_d(i_d, -i_q) =
psi_d(i_d, i_q)`` and ``psi_q(i_d, -i_q) = -psi_q(i_d, i_q)``: reversing the q current mirrors the field
about the d axis. The unknowns are therefore the nodes of the half grid ``i_q >= 0`` (``psi_q = 0`` on
``i_q = 0``), and the full grid, symmetric about ``i_q = 0``, is their mirror image (`_mirror_expansion`):
a sample at ``i_q < 0`` counts as its mirror image at ``-i_q`` with psi_q's sign flipped (for the
equations, the measured marks and the grid's extent), the interpolant's slope ``dpsi_d/di_q`` at
``i_q = 0`` is zero (central differences of mirrored nodes), and the written map is symmetric exactly. The
torque ``1.5 p (psi_d i_q - psi_q i_d)`` is then odd in i_q, so the MTPA locus's generating half is the
motoring half's mirror image: a log that motors only determines both, one that visits both signs averages
them. motulator's SyR-e import mirrors measured maps the same way (``import_syre_data``,
``add_negative_q_axis``, Aalto-Electric-Drives/motulator), and the power-law magnetic model of Hinkkanen,
Pescetto, Mölsä, Saarakkala, Pellegrino and Bojoi, IEEE Trans. Ind. Appl., 2017,
doi:10.1109/TIA.2016.2644624, depends on ``|psi_q|`` only. It fails for a rotor that is not symmetric
about d (barriers or magnets shifted or shaped asymmetrically to cut torque ripple, a skew whose end
effects differ between the two ends): ``q_symmetric=False`` (``--no-q-symmetry``) fits every node from
the log, which must then visit both torque signs. The default grid step is the recorded currents'
([`grid_step`][tuning.identify.flux_map_fit.grid_step]: its thresholds are calibrated on recorded logs).

**Nodes the log does not reach** are determined by a weak smoothness prior (second differences along each
axis, weight [`SMOOTHNESS`][tuning.identify.flux_map_fit.SMOOTHNESS]) and the constraints below; a node
is *measured* when at least [`MIN_NODE_SAMPLES`][tuning.identify.flux_map_fit.MIN_NODE_SAMPLES] samples lie
within half a grid step of it along both axes, and the written map marks the others
([`pmsmjax.io.flux_map_files.read_flux_map_measured`][pmsmjax.io.flux_map_files.read_flux_map_measured]).
Such a node rests on a few transient samples or on none, and the grid's edge rows set the inductance the
map is extended with beyond the grid
([`pmsmjax.machines.flux_map.flux_and_inductance`][pmsmjax.machines.flux_map.flux_and_inductance]), where a
drive file's MTPA check looks up to the grid's corner current
([`pmsmjax.spec.design_rules`][pmsmjax.spec.design_rules]); a map that fails it is written, and the check
refuses ``motor.toml`` with its own message. Measured with the d-axis symmetry: the flux-map notebook's 3 x 5
staircase of the saturated IPM (six seeds), its walk, its log of ordinary operation and the reluctance
machine's motoring-only staircase all pass at the one weak prior weight. Fitted without the symmetry, the
notebook's staircase at seed 1 and the ordinary-operation log at a 2 A grid fail the check at the grid's
unvisited corner, and the reluctance staircase in the generating half-plane it never visits.

**A map that stores energy, as a constraint.** A log of ordinary operation moves its currents along one
path, fixing the flux along it and the nodes either side only in combination; a walk's nodes between its
dwells rest on a few noisy transient samples. Fitted freely, such nodes can form a map whose incremental
inductance is not positive definite or whose flux falls with its current. The fit is therefore the least
squares under linear inequalities that exclude this at every node
([`tuning.identify.flux_map_constraints`][tuning.identify.flux_map_constraints]), the prior unchanged. A
log whose free fit stores no energy at more than
[`CONTRADICTED_SHARE`][tuning.identify.flux_map_fit.CONTRADICTED_SHARE] of the measured nodes, or whose
residual the constraints raise by more than
[`RESIDUAL_GROWTH`][tuning.identify.flux_map_fit.RESIDUAL_GROWTH], contradicts any flux map (swapped or
sign-flipped columns) and is refused in one line.
"""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import minimize_scalar

from pmsmjax.machines.flux_map import FluxMapGrid, flux_and_inductance, hermite_coefficients
from pmsmjax.spec.design_rules import round_up_nice
from pmsmjax.spec.validation import ParameterError, plain
from tuning.identify.electrical import _dead_time_voltage
from tuning.identify.flux_map_constraints import (
    factor,
    free_solution,
    slope_operators,
    solve_constrained,
    symmetric_inductances,
)

__all__ = [
    "FluxMapFit",
    "fit_flux_map",
    "flux_map_axes",
    "grid_step",
    "SPEED_JUMP",
    "MIN_NODE_SAMPLES",
    "SMOOTHNESS",
    "RESIDUAL_GROWTH",
    "CONTRADICTED_SHARE",
    "ENDPOINT_SAMPLES",
]

#: An interval whose electrical speed changes by more than this share of the top speed is a reversal.
SPEED_JUMP = 0.05
#: Samples within half a step of a node (both axes) for it to count as measured.
MIN_NODE_SAMPLES = 5
#: Weight of the smoothness prior's second differences against the window equations (Wb per Wb).
SMOOTHNESS = 0.02
#: The least incremental inductance (every direction, every node) of the energy-storing map, as a share of the
#: median own-axis node inductance of the unconstrained fit at the measured nodes.
INDUCTANCE_FLOOR_SHARE = 0.02
#: Growth of the window residual (RMS) under the energy-storing constraints beyond which the data are taken
#: to contradict any such map (swapped or sign-flipped columns).
RESIDUAL_GROWTH = 1.5
#: Share of the measured nodes at which the unconstrained fit stores no energy beyond which the data are taken
#: to contradict any flux map (a noisy log's free fit breaks at a few nodes, a swapped column's at most).
CONTRADICTED_SHARE = 0.25
#: Samples each window's ends are averaged over (the mean of that many windows, each one sample later).
ENDPOINT_SAMPLES = 4
#: Smallest share of the log's top speed accepted as "turning": below it the back-EMF hides the flux.
MIN_SPEED_SHARE = 0.05
#: Range of the inverter error's fitted sign width as shares of the largest logged current.
SMOOTHING_BOUNDS = (1e-3, 0.3)
#: Most and fewest grid intervals over the wider visited current range the default step may give.
FINEST_INTERVALS, COARSEST_INTERVALS = 40, 3
#: Samples near a node (within half a step, both axes) for the default step to count it dense
#: ([`grid_step`][tuning.identify.flux_map_fit.grid_step]).
DENSE_NODE_SAMPLES = 25


@dataclasses.dataclass(frozen=True)
class FluxMapFit:
    """The identified map.

    - `grid`: [`FluxMapGrid`][pmsmjax.machines.flux_map.FluxMapGrid] (every node: the fit's value; unmeasured
      ones from the prior only);
    - `measured`: ``(n_d, n_q)`` bool, nodes the log reached (module docstring);
    - `R`: ohm (`R_fixed`: given, not fitted); `V_e`: inverter voltage error per phase, V (None: not fitted);
    - `error_smoothing_a`: the current, A, over which the inverter error's sign turns (``tanh(i / eps)``;
      fitted unless given; None when ``V_e`` is not fitted);
    - `residual_rms_wb`: RMS of the window equations at the solution, Wb;
    - `n_windows`: windows used; `node_samples`: ``(n_d, n_q)`` samples near each node;
    - `constraints`: the energy-storing inequalities the fit imposed (0: the free fit stored energy
      everywhere; module docstring);
    - `q_symmetric`: fitted on the half grid ``i_q >= 0`` and mirrored (module docstring, "The d-axis
      symmetry"); the grid is then symmetric about ``i_q = 0``.
    """

    grid: FluxMapGrid
    measured: np.ndarray
    R: float
    R_fixed: bool
    V_e: float | None
    residual_rms_wb: float
    n_windows: int
    node_samples: np.ndarray
    error_smoothing_a: float | None = None
    constraints: int = 0
    q_symmetric: bool = True


def _axes(i_dq: np.ndarray, step_a: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid axes of step ``step_a`` A over the currents ``i_dq (N, 2)``, snapped to multiples of the step."""
    lo, hi = i_dq.min(axis=0), i_dq.max(axis=0)
    axes = []
    for a in range(2):
        first, last = math.floor(lo[a] / step_a), math.ceil(hi[a] / step_a)
        last = max(last, first + 2)  # the interpolant needs three points per axis
        axes.append(step_a * np.arange(first, last + 1))
    return axes[0], axes[1]


def grid_step(i_dq: np.ndarray) -> float:
    """The default grid step, A, for the currents ``i_dq (N, 2)``: the finest 1-2-2.5-5 step (between a
    `FINEST_INTERVALS`-th and a `COARSEST_INTERVALS`-th of the wider visited range) at which
    three quarters of the visited places lie nearest to a node with at least `DENSE_NODE_SAMPLES` samples
    within half a step (a place: a cell of a hundredth of the wider range that holds a sample, each counted
    once, so a dwell weighs as much as the path of a transient of its size). Finer, the nodes between the
    dwells of a staircase or along a path rest on too few noisy samples; coarser, the interpolant's error
    between nodes grows as the step cubed."""
    span = float(np.max(np.ptp(i_dq, axis=0)))
    cell = span / 100.0
    places = np.unique(np.round(i_dq / cell), axis=0) * cell
    step = round_up_nice(span / FINEST_INTERVALS)
    while step < span / COARSEST_INTERVALS:
        i_d, i_q = _axes(i_dq, step)
        counts = _node_samples(i_dq, i_d, i_q)
        j = np.clip(np.round((places[:, 0] - i_d[0]) / step).astype(int), 0, i_d.size - 1)
        k = np.clip(np.round((places[:, 1] - i_q[0]) / step).astype(int), 0, i_q.size - 1)
        if np.quantile(counts[j, k], 0.25) >= DENSE_NODE_SAMPLES:
            return step
        step = round_up_nice(step * 1.01)
    return step


def flux_map_axes(i_dq: np.ndarray, step_a: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(i_d (n_d,), i_q (n_q,))`` grid axes, A, covering the currents ``i_dq (N, 2)`` with ``step_a`` A
    (default: [`grid_step`][tuning.identify.flux_map_fit.grid_step])."""
    return _axes(i_dq, grid_step(i_dq) if step_a is None else step_a)


def _node_samples(i_dq, i_d, i_q):
    """``(n_d, n_q)``: samples of ``i_dq (N, 2)`` within half a step of each node along both axes."""
    h = np.array([i_d[1] - i_d[0], i_q[1] - i_q[0]])
    j = np.round((i_dq[:, 0] - i_d[0]) / h[0]).astype(int)
    k = np.round((i_dq[:, 1] - i_q[0]) / h[1]).astype(int)
    inside = (j >= 0) & (j < i_d.size) & (k >= 0) & (k < i_q.size)
    counts = np.zeros((i_d.size, i_q.size), dtype=int)
    np.add.at(counts, (j[inside], k[inside]), 1)
    return counts


def _ramp_mean(x, K: int):
    """``(N - K + 1, ...)``: the mean of ``x (N, ...)`` over each run of ``K`` samples from each sample on."""
    if K == 1:
        return x
    c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])
    return (c[K:] - c[:-K]) / K


def _voltage_integrals(u, w_e, dt, hold):
    """``(N-1, 2)`` integral of the held dq voltage over each interval, V s."""
    if hold == "rotor":
        return u[:-1] * dt[:, None]
    x = w_e[:-1] * dt
    small = np.abs(x) < 1e-8
    xs = np.where(small, 1.0, x)
    a = np.where(small, 1.0, np.sin(xs) / xs)
    b = np.where(small, 0.5 * x, (1.0 - np.cos(xs)) / xs)
    # u_d(t) = cos u_d + sin u_q, u_q(t) = -sin u_d + cos u_q with the angle w_e (t - t_k)
    return dt[:, None] * np.stack([a * u[:-1, 0] + b * u[:-1, 1], -b * u[:-1, 0] + a * u[:-1, 1]], -1)


def _basis(i_dq, i_d, i_q):
    """``(N, n_d, n_q)``: the interpolant at each current as weights of the node fluxes (d/dP, exact:
    the interpolant is linear in the nodes)."""
    step = jnp.array([i_d[1] - i_d[0], i_q[1] - i_q[0]])
    lower, upper = jnp.array([i_d[0], i_q[0]]), jnp.array([i_d[-1], i_q[-1]])

    def flux(nodes, i):
        C = hermite_coefficients(jnp.stack([nodes, nodes]), step, jnp)
        return flux_and_inductance(C, lower, step, upper, i, jnp)[0][0]

    zeros = jnp.zeros((i_d.size, i_q.size))
    weights = jax.jit(jax.vmap(jax.jacfwd(flux), in_axes=(None, 0)))
    return np.asarray(weights(zeros, jnp.asarray(i_dq)))


def _second_differences(n_d, n_q):
    """``((M, n_d n_q), (M,))``: the second differences along i_d and along i_q of a raveled node array,
    and the raveled index of the node each is centred on."""
    rows, centres = [], []
    index = np.arange(n_d * n_q).reshape(n_d, n_q)
    for j in range(n_d):
        for k in range(n_q):
            for dj, dk in ((1, 0), (0, 1)):
                if 0 < j < n_d - 1 or dj == 0:
                    if 0 < k < n_q - 1 or dk == 0:
                        row = np.zeros(n_d * n_q)
                        row[index[j - dj, k - dk]] += 1.0
                        row[index[j, k]] -= 2.0
                        row[index[j + dj, k + dk]] += 1.0
                        rows.append(row)
                        centres.append(index[j, k])
    return np.array(rows), np.array(centres)


@jax.jit
def _error_basis(i_dq, cs, eps):
    return jax.vmap(lambda i, c: _dead_time_voltage(i, c, eps))(i_dq, cs)


def _inverter_error_per_volt(i_dq, theta_e, eps: float) -> np.ndarray:
    """``(N, 2)`` dq voltage, V, lost to an inverter error of one volt per phase whose sign is
    ``tanh(i_x / eps)`` of each phase current, at the log's currents ``i_dq (N, 2)`` A and angles
    ``theta_e (N,)`` rad."""
    cs = np.stack([np.cos(theta_e), np.sin(theta_e)], -1)
    with jax.enable_x64(True):
        return np.asarray(_error_basis(jnp.asarray(i_dq), jnp.asarray(cs), jnp.asarray(float(eps))))


def _profiled_smoothing(cost, i_dq) -> float:
    """The sign's smoothing current, A, that minimises ``cost(eps)`` (the least-squares sum with every
    other unknown solved for: a variable-projection profile, Golub and Pereyra, Inverse Problems 19(2),
    2003, doi:10.1088/0266-5611/19/2/201), searched on a log scale between `SMOOTHING_BOUNDS` shares
    of the largest logged current.

    Why fitted: the width over which a real bridge's error turns is set by the PWM current ripple (and
    the current sensor's noise blurs the sign the fit sees), and a width off by a factor of a few biases
    ``V_e`` by ~10 % and R further, since near a zero crossing the error grows with the current as a
    resistance does."""
    top = float(np.max(np.abs(i_dq)))
    lo, hi = (math.log(share * top) for share in SMOOTHING_BOUNDS)
    best = minimize_scalar(
        lambda z: cost(math.exp(z)), bounds=(lo, hi), method="bounded", options={"xatol": 0.02}
    )
    return float(math.exp(best.x))


def _checked_speed(log, pole_pairs: int, R) -> tuple[np.ndarray, np.ndarray]:
    """``(w_e (N,) rad/s, dt (N-1,) s)`` of ``log``, refusing in one line a log that hardly turns, and one
    that turns one way only when ``R`` (ohm) is not given (module docstring, "Separability")."""
    where = log.source
    dt = np.diff(log.time)
    w_e = pole_pairs * np.asarray(log.omega_m, dtype=float)
    top = float(np.max(np.abs(w_e)))
    turning = np.abs(w_e) > MIN_SPEED_SHARE * max(top, 1e-300)
    if top * float(np.median(dt)) < 1e-6 or turning.mean() < 0.5:
        raise ParameterError(
            f"{where}: the rotor hardly turns (top speed {plain(top / pole_pairs)} rad/s mechanical, "
            f"turning in "
            f"{100 * turning.mean():.0f} % of the log): a flux map is seen through the back-EMF w_e psi, "
            "record the map at speed (a dynamometer holding e.g. a third of the rated speed)."
        )
    both_ways = min((w_e > MIN_SPEED_SHARE * top).mean(), (w_e < -MIN_SPEED_SHARE * top).mean()) > 0.1
    if R is None and not both_ways:
        raise ParameterError(
            f"{where}: the rotor turns one way only, so R is not separated from the flux (u = R i + "
            "w_e J psi "
            "at steady state): give --fix R=VALUE (ohm, e.g. a DC measurement) or record the walk in both "
            "directions of rotation."
        )
    return w_e, dt


@dataclasses.dataclass(frozen=True)
class WindowEquations:
    """What the window equations of a log need besides the flux (module docstring): `starts` ``(W,)``,
    `a`, `b` ``(W,)`` the (averaged) ends of each window, sample indices; `K` samples each end is averaged
    over; `half` ``(N-1, 1)`` half the interval lengths, s; `U_int`, `I_int` ``(N-K+1, 2)`` running integrals
    of the held voltage (V s) and of the current (A s), each end-averaged; `cum` maps per-interval values
    ``(N-1, ...)`` to such end-averaged running sums."""

    starts: np.ndarray
    a: np.ndarray
    b: np.ndarray
    K: int
    half: np.ndarray
    U_int: np.ndarray
    I_int: np.ndarray
    cum: object


def window_equations(log, w_e, dt, window_s: float, stride: int) -> WindowEquations:
    """The windows of ``log`` (``window_s`` s long, one every ``stride`` samples, none across a speed
    reversal) and the integrals their equations need; ``w_e``, ``dt`` as `_checked_speed` gives them."""
    window = max(2, round(window_s / float(np.median(dt))))
    jump = np.abs(np.diff(w_e)) > SPEED_JUMP * float(np.max(np.abs(w_e)))  # intervals not to integrate across
    K = ENDPOINT_SAMPLES
    starts = np.arange(0, log.n - window - K + 1, stride)
    jumped = np.concatenate([[0], np.cumsum(jump)])
    starts = starts[jumped[starts + window + K - 1] == jumped[starts]]
    if starts.size == 0:
        raise ParameterError(
            f"{log.source}: no window of {window_s} s without a speed reversal: record longer."
        )
    i_dq = np.asarray(log.i_dq, dtype=float)
    U = _voltage_integrals(np.asarray(log.u_dq, dtype=float), w_e, dt, log.hold)
    half = 0.5 * dt[:, None]
    # per interval: the trapezoid weights of each sample (N-1 intervals -> cumulative sums over windows)
    cum = lambda x: _ramp_mean(np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)]), K)  # noqa: E731
    return WindowEquations(
        starts=starts,
        a=starts,
        b=starts + window,
        K=K,
        half=half,
        U_int=cum(U),
        I_int=cum(half * (i_dq[:-1] + i_dq[1:])),
        cum=cum,
    )


def fit_flux_map(
    log,
    pole_pairs: int,
    *,
    step_a: float | None = None,
    window_s: float = 2e-3,
    stride: int = 2,
    R: float | None = None,
    inverter_error: bool = False,
    error_smoothing_a: float | None = None,
    q_symmetric: bool = True,
) -> FluxMapFit:
    """Identify the flux map of ``log`` (a [`tuning.identify.log.DriveLog`][tuning.identify.log.DriveLog])
    with ``pole_pairs``; module docstring. `step_a`: grid step, A (default
    [`flux_map_axes`][tuning.identify.flux_map_fit.flux_map_axes]); `window_s`: window length, s; `stride`:
    samples between window starts; `R`: ohm, held fixed when given; `inverter_error`: fit the inverter voltage
    error ``V_e`` (V per phase, its sign smoothed over `error_smoothing_a` A; default: that width fitted too,
    `_profiled_smoothing`); `q_symmetric`: the rotor is symmetric about its d axis, the map fitted on
    ``i_q >= 0`` and mirrored (module docstring; False for a rotor that is not). Raises
    [`ParameterError`][pmsmjax.spec.validation.ParameterError] (one line) for a log it cannot use."""
    where = log.source
    w_e, dt = _checked_speed(log, pole_pairs, R)
    if step_a is not None and not (math.isfinite(step_a) and step_a > 0):
        raise ParameterError(f"--flux-map-step {step_a!r}: give a positive grid step in A, e.g. 2.")
    i_dq = np.asarray(log.i_dq, dtype=float)
    # with the d-axis symmetry every sample at i_q < 0 is one at -i_q (psi_q's sign flipped): the grid and
    # the measured marks are those of the folded currents, on the half grid from i_q = 0; the default step
    # is the recorded currents' (folding merges the places either side of i_q = 0, and the rule's
    # thresholds are calibrated on the recorded logs)
    i_fold = np.column_stack([i_dq[:, 0], np.abs(i_dq[:, 1])]) if q_symmetric else i_dq
    i_d, i_q = flux_map_axes(i_fold, grid_step(i_dq) if step_a is None else step_a)
    if q_symmetric:
        i_q = (i_q[1] - i_q[0]) * np.arange(0, round(i_q[-1] / (i_q[1] - i_q[0])) + 1)
    node_samples = _node_samples(i_fold, i_d, i_q)
    # the grid ends at the last rows and columns the log reaches (outside: the linear extension)
    rows, cols = (
        np.flatnonzero(node_samples.max(1) >= MIN_NODE_SAMPLES),
        np.flatnonzero(node_samples.max(0) >= MIN_NODE_SAMPLES),
    )
    if rows.size and cols.size:
        j0, j1 = min(rows[0], max(rows[-1] - 2, 0)), max(rows[-1], rows[0] + 2)
        k0, k1 = min(cols[0], max(cols[-1] - 2, 0)), max(cols[-1], cols[0] + 2)
        if q_symmetric:  # the half grid starts at i_q = 0, where the mirror image joins it
            k0, k1 = 0, max(cols[-1], 2)
        i_d, i_q = i_d[j0 : j1 + 1], i_q[k0 : k1 + 1]
        node_samples = node_samples[j0 : j1 + 1, k0 : k1 + 1]
    n_half = i_q.size
    if q_symmetric:  # the full grid: the half and its mirror image, symmetric about i_q = 0
        i_q = np.concatenate([-i_q[:0:-1], i_q])
        node_samples = np.concatenate([node_samples[:, :0:-1], node_samples], axis=1)
    h = np.array([i_d[1] - i_d[0], i_q[1] - i_q[0]])
    n_d, n_q = i_d.size, i_q.size
    measured = node_samples >= MIN_NODE_SAMPLES
    if measured.sum() < 4:
        raise ParameterError(
            f"{where}: the currents visit no region a map can be fitted on "
            f"({int(measured.sum())} grid points "
            f"of {plain(h[0])} A have {MIN_NODE_SAMPLES} samples near them; i_d {plain(i_dq[:, 0].min())} to "
            f"{plain(i_dq[:, 0].max())} A, i_q {plain(i_dq[:, 1].min())} to {plain(i_dq[:, 1].max())} A): "
            "walk "
            "a grid of current operating points, or give a finer --flux-map-step."
        )
    windows = window_equations(log, w_e, dt, window_s, stride)
    starts, a, b, K, cum = windows.starts, windows.a, windows.b, windows.K, windows.cum
    with jax.enable_x64(True):
        B = _basis(i_dq, i_d, i_q).reshape(log.n, -1)  # (N, nodes)
    half = windows.half
    Bw = w_e[:, None] * B  # w_e psi weights per sample
    W_int = cum(half * (Bw[:-1] + Bw[1:]))  # (N, nodes) running integral of w_e psi
    n_nodes = n_d * n_q
    # rows d: psi_d(b) - psi_d(a) - int w_e psi_q + R int i_d + V_e int e_d = int u_d
    # rows q: psi_q(b) - psi_q(a) + int w_e psi_d + R int i_q + V_e int e_q = int u_q
    B = _ramp_mean(B, K)
    dB = B[b] - B[a]
    dW = W_int[b] - W_int[a]
    rows_d = np.hstack([dB, -dW])
    rows_q = np.hstack([dW, dB])
    A = np.vstack([rows_d, rows_q])
    # the unknowns: every node's fluxes, or (d-axis symmetry) the half grid's, x = E y (`_mirror_expansion`)
    E = _mirror_expansion(n_d, n_half) if q_symmetric else None
    if E is not None:
        A = A @ E
    n_unknown_nodes = A.shape[1]
    over_window = lambda x: np.concatenate([x[b, 0] - x[a, 0], x[b, 1] - x[a, 1]])  # noqa: E731
    rhs = over_window(windows.U_int)
    if R is None:
        A = np.hstack([A, over_window(windows.I_int)[:, None]])
    else:
        rhs = rhs - R * over_window(windows.I_int)
    D, centres = _second_differences(n_d, n_q)
    n_columns = A.shape[1] + inverter_error
    prior_nodes = np.zeros((2 * D.shape[0], 2 * n_nodes))
    prior_nodes[: D.shape[0], :n_nodes] = D
    prior_nodes[D.shape[0] :, n_nodes:] = D
    centres = np.tile(centres, 2)
    if E is not None:
        # a row centred at i_q < 0 repeats its mirror image's; those at i_q = 0 along i_q say
        # psi_q(1) - psi_q(-1) = 0 of psi_q (no row) and 2 (psi_d(1) - psi_d(0)) of psi_d
        prior_nodes = prior_nodes @ E
        keep = (i_q[centres % n_q] >= 0) & np.any(prior_nodes != 0, axis=1)
        prior_nodes, centres = prior_nodes[keep], centres[keep]
    prior = np.zeros((len(prior_nodes), n_columns))
    prior[:, :n_unknown_nodes] = prior_nodes
    scale = np.sqrt(A.shape[0] / max(prior.shape[0], 1))  # the prior weighs like as many rows as the data
    prior_rhs = np.zeros(len(prior))
    S_d, S_q = slope_operators(n_d, n_q, h)

    def solve(eps, constrained=False):
        """``(x, A, cost, cuts)``: the least-squares solution with the error's sign smoothed over ``eps`` A
        (energy-storing when ``constrained``, `tuning.identify.flux_map_constraints`), the window
        equations' matrix, the sum of squares (prior included) and the number of constraints it took."""
        A_eps = A
        if inverter_error:
            e = _inverter_error_per_volt(i_dq, log.theta_e, eps)
            E_int = cum(half * (e[:-1] + e[1:]))
            A_eps = np.hstack([A, over_window(E_int)[:, None]])
        M = np.vstack([A_eps, SMOOTHNESS * scale * prior])
        target = np.concatenate([rhs, prior_rhs])
        cuts = 0
        factored = factor(M, target)
        if constrained:
            x, cuts = solve_constrained(factored, n_d, n_q, h, floor_h, where, expand_all, checked)
        else:
            x = free_solution(factored)
        return x, A_eps, float(np.sum((M @ x - target) ** 2)), cuts

    eps = error_smoothing_a
    if inverter_error and eps is None:
        eps = _profiled_smoothing(lambda e: solve(e)[2], i_dq)
    # the full unknown vector [psi_d nodes, psi_q nodes, R, V_e] of the fitted one
    expand_all = None if E is None else _with_identity(E, n_columns - n_unknown_nodes)
    full = (lambda y: y) if E is None else (lambda y: expand_all @ y)  # noqa: E731
    checked = i_q[np.arange(n_nodes) % n_q] >= 0 if E is not None else None  # the rest mirror these
    x_free, A_fit, _, _ = solve(eps)
    L_free = symmetric_inductances(full(x_free), S_d, S_q)[measured.ravel()]
    own = np.concatenate([L_free[:, 0, 0], L_free[:, 1, 1]])
    floor_h = INDUCTANCE_FLOOR_SHARE * max(float(np.median(np.abs(own))), 1e-12)
    contradicted = int(np.sum(np.linalg.eigvalsh(L_free)[:, 0] <= 0.0))
    try:
        if contradicted > CONTRADICTED_SHARE * len(L_free):
            raise ParameterError(
                f"{where}: fitted freely, the map stores no energy at {contradicted} of the {len(L_free)} "
                "grid points the log reaches."
            )
        x, A_fit, _, cuts = solve(eps, constrained=True)
        growth = np.sqrt(np.sum((A_fit @ x - rhs) ** 2) / max(np.sum((A_fit @ x_free - rhs) ** 2), 1e-300))
        if growth > RESIDUAL_GROWTH:
            raise ParameterError(
                f"{where}: the energy-storing map leaves {growth:.3g} times the window residual of an "
                "unconstrained one."
            )
    except ParameterError as err:
        failure = str(err).split(": ", 1)[1]
        lo, hi = i_dq.min(axis=0), i_dq.max(axis=0)
        visited = f"i_d {plain(lo[0])} to {plain(hi[0])} A, i_q {plain(lo[1])} to {plain(hi[1])} A"
        reached = f"{int(measured.sum())} of {measured.size} grid points of {plain(h[0])} A"
        raise ParameterError(
            f"{where}: the identified map is not a usable flux map ({failure} The log's currents reach "
            f"{reached}, {visited}.) The data contradict a map that stores energy: check the column "
            "order and signs of the voltages and currents."
        ) from None
    nodes = full(x)
    psi_d, psi_q = nodes[:n_nodes].reshape(n_d, n_q), nodes[n_nodes : 2 * n_nodes].reshape(n_d, n_q)
    grid = FluxMapGrid(i_d, i_q, psi_d, psi_q, source="identified flux map")
    residual = A_fit @ x - rhs
    k = n_unknown_nodes
    R_fit = float(x[k]) if R is None else float(R)
    V_e = float(x[k + (R is None)]) if inverter_error else None
    return FluxMapFit(
        grid=grid,
        measured=measured,
        R=R_fit,
        R_fixed=R is not None,
        V_e=V_e,
        residual_rms_wb=float(np.sqrt(np.mean(residual**2))),
        n_windows=int(starts.size),
        node_samples=node_samples,
        error_smoothing_a=float(eps) if inverter_error else None,
        constraints=cuts,
        q_symmetric=q_symmetric,
    )


def _mirror_expansion(n_d: int, n_half: int) -> np.ndarray:
    """``(2 n_d n_q, n_d (2 n_half - 1))`` with ``n_q = 2 n_half - 1``: the raveled full-grid node fluxes
    ``[psi_d, psi_q]`` (i_q from ``-(n_half - 1)`` to ``n_half - 1`` steps) of the half grid's unknowns
    ``[psi_d (n_d, n_half), psi_q (n_d, n_half - 1)]`` (i_q from 0, resp. one step, up): ``psi_d`` even in
    i_q, ``psi_q`` odd, so ``psi_q = 0`` at ``i_q = 0``, and the interpolant's central-difference slope
    ``dpsi_d/di_q`` there is zero (module docstring, "d-axis symmetry")."""
    n_q = 2 * n_half - 1
    offset = np.arange(n_q) - (n_half - 1)  # full column's signed distance from i_q = 0, steps
    k, sign = np.abs(offset), np.sign(offset)
    E_d = np.zeros((n_d, n_q, n_d, n_half))
    E_q = np.zeros((n_d, n_q, n_d, n_half - 1))
    for j in range(n_d):
        E_d[j, np.arange(n_q), j, k] = 1.0
        odd = k > 0
        E_q[j, np.flatnonzero(odd), j, k[odd] - 1] = sign[odd]
    n = n_d * n_q
    E = np.zeros((2 * n, E_d[0, 0].size + E_q[0, 0].size))
    E[:n, : E_d[0, 0].size] = E_d.reshape(n, -1)
    E[n:, E_d[0, 0].size :] = E_q.reshape(n, -1)
    return E


def _with_identity(E: np.ndarray, extra: int) -> np.ndarray:
    """``E`` extended by ``extra`` unknowns (R, V_e) that map to themselves."""
    out = np.zeros((E.shape[0] + extra, E.shape[1] + extra))
    out[: E.shape[0], : E.shape[1]] = E
    out[E.shape[0] :, E.shape[1] :] = np.eye(extra)
    return out
