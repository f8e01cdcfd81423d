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

**Nodes the log does not reach** are determined by nothing but a weak smoothness prior (second
differences along each axis, weight [`SMOOTHNESS`][tuning.identify.flux_map_fit.SMOOTHNESS]); a node
is *measured* when at least [`MIN_NODE_SAMPLES`][tuning.identify.flux_map_fit.MIN_NODE_SAMPLES] samples lie
within half a grid step of it along both axes, and the written map marks the others
([`pmsmjax.io.flux_map_files.read_flux_map_measured`][pmsmjax.io.flux_map_files.read_flux_map_measured]).

**Logs of ordinary operation.** A speed-controlled drive with a fixed d-current rule moves its currents
along one path through the current plane. The data then fix the flux along the path, and the nodes on
either side of it only in combination: the interpolant's representation error along the path can tilt
them into a map that stores no energy or whose flux falls with its current. The prior's weight is
therefore the least of ``SMOOTHNESS * 2**k``, ``k <= SMOOTHNESS_STEPS``, whose map passes the flux-map
checks (a walk over a grid passes at ``k = 0``); a log that fails at every weight is refused in one
line (measured on a SciPy log of speed steps and load steps:
``tests/tuning/test_identify_flux_map.py``).
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

__all__ = ["FluxMapFit", "fit_flux_map", "flux_map_axes", "SPEED_JUMP", "MIN_NODE_SAMPLES", "SMOOTHNESS"]

#: An interval whose electrical speed changes by more than this share of the top speed is a reversal.
SPEED_JUMP = 0.05
#: Samples within half a step of a node (both axes) for it to count as measured.
MIN_NODE_SAMPLES = 5
#: Weight of the smoothness prior's second differences against the window equations (Wb per Wb): the
#: first one tried (`SMOOTHNESS_STEPS`).
SMOOTHNESS = 0.02
#: Times [`SMOOTHNESS`][tuning.identify.flux_map_fit.SMOOTHNESS] is doubled at most while the fitted map fails
#: the flux-map checks.
SMOOTHNESS_STEPS = 5
#: Smallest share of the log's top speed accepted as "turning": below it the back-EMF hides the flux.
MIN_SPEED_SHARE = 0.05
#: Weight of the prior's second differences among nodes the log does not reach, against
#: [`SMOOTHNESS`][tuning.identify.flux_map_fit.SMOOTHNESS] elsewhere: there the map continues its neighbours
#: almost linearly, it is not fitted.
UNMEASURED_SMOOTHNESS = 50.0
#: Range of the inverter error's fitted sign width as shares of the largest logged current.
SMOOTHING_BOUNDS = (1e-3, 0.3)
#: Fewest grid intervals per axis the default step gives over the visited range.
DEFAULT_INTERVALS = 8


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
    - `smoothness`: the weight of the smoothness prior the map was fitted with (module docstring).
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
    smoothness: float = SMOOTHNESS


def flux_map_axes(i_dq: np.ndarray, step_a: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(i_d (n_d,), i_q (n_q,))`` grid axes, A, covering the currents ``i_dq (N, 2)`` with ``step_a`` A
    (default: a 1-2-2.5-5 step giving about `DEFAULT_INTERVALS` intervals over the wider range)."""
    lo, hi = i_dq.min(axis=0), i_dq.max(axis=0)
    if step_a is None:
        step_a = round_up_nice(float(np.max(hi - lo)) / DEFAULT_INTERVALS)
    axes = []
    for a in range(2):
        first, last = math.floor(lo[a] / step_a), math.ceil(hi[a] / step_a)
        last = max(last, first + 2)  # the interpolant needs three points per axis
        axes.append(step_a * np.arange(first, last + 1))
    return axes[0], axes[1]


def _node_samples(i_dq, i_d, i_q):
    """``(n_d, n_q)``: samples of ``i_dq (N, 2)`` within half a step of each node along both axes."""
    h = np.array([i_d[1] - i_d[0], i_q[1] - i_q[0]])
    j = np.round((i_dq[:, 0] - i_d[0]) / h[0]).astype(int)
    k = np.round((i_dq[:, 1] - i_q[0]) / h[1]).astype(int)
    inside = (j >= 0) & (j < i_d.size) & (k >= 0) & (k < i_q.size)
    counts = np.zeros((i_d.size, i_q.size), dtype=int)
    np.add.at(counts, (j[inside], k[inside]), 1)
    return counts


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
    """``((M, n_d n_q) rows, (M,) centre node)``: second differences along i_d and along i_q of a node
    array and the node each is centred on."""
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
) -> FluxMapFit:
    """Identify the flux map of ``log`` (a [`tuning.identify.log.DriveLog`][tuning.identify.log.DriveLog])
    with ``pole_pairs``; module docstring. `step_a`: grid step, A (default
    [`flux_map_axes`][tuning.identify.flux_map_fit.flux_map_axes]); `window_s`: window length, s; `stride`:
    samples between window starts; `R`: ohm, held fixed when given; `inverter_error`: fit the inverter voltage
    error ``V_e`` (V per phase, its sign smoothed over `error_smoothing_a` A; default: that width fitted too,
    `_profiled_smoothing`). Raises [`ParameterError`][pmsmjax.spec.validation.ParameterError] (one line) for
    a log it cannot use."""
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
    if step_a is not None and not (math.isfinite(step_a) and step_a > 0):
        raise ParameterError(f"--flux-map-step {step_a!r}: give a positive grid step in A, e.g. 2.")
    i_dq = np.asarray(log.i_dq, dtype=float)
    i_d, i_q = flux_map_axes(i_dq, step_a)
    node_samples = _node_samples(i_dq, i_d, i_q)
    # the grid ends at the last rows and columns the log reaches (outside: the linear extension)
    rows, cols = (
        np.flatnonzero(node_samples.max(1) >= MIN_NODE_SAMPLES),
        np.flatnonzero(node_samples.max(0) >= MIN_NODE_SAMPLES),
    )
    if rows.size and cols.size:
        j0, j1 = min(rows[0], max(rows[-1] - 2, 0)), max(rows[-1], rows[0] + 2)
        k0, k1 = min(cols[0], max(cols[-1] - 2, 0)), max(cols[-1], cols[0] + 2)
        i_d, i_q = i_d[j0 : j1 + 1], i_q[k0 : k1 + 1]
        node_samples = node_samples[j0 : j1 + 1, k0 : k1 + 1]
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
    window = max(2, round(window_s / float(np.median(dt))))
    jump = np.abs(np.diff(w_e)) > SPEED_JUMP * top  # (N-1,) intervals not to integrate across
    starts = np.arange(0, log.n - window, stride)
    jumped = np.concatenate([[0], np.cumsum(jump)])
    starts = starts[jumped[starts + window] == jumped[starts]]
    if starts.size == 0:
        raise ParameterError(f"{where}: no window of {window_s} s without a speed reversal: record longer.")

    with jax.enable_x64(True):
        B = _basis(i_dq, i_d, i_q).reshape(log.n, -1)  # (N, nodes)
    U = _voltage_integrals(np.asarray(log.u_dq, dtype=float), w_e, dt, log.hold)
    half = 0.5 * dt[:, None]
    # per interval: the trapezoid weights of each sample (N-1 intervals -> cumulative sums over windows)
    cum = lambda x: np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])  # noqa: E731
    I_int = cum(half * (i_dq[:-1] + i_dq[1:]))  # (N, 2) running integral of i
    U_int = cum(U)
    Bw = w_e[:, None] * B  # w_e psi weights per sample
    W_int = cum(half * (Bw[:-1] + Bw[1:]))  # (N, nodes) running integral of w_e psi
    a, b = starts, starts + window
    n_nodes = n_d * n_q
    # rows d: psi_d(b) - psi_d(a) - int w_e psi_q + R int i_d + V_e int e_d = int u_d
    # rows q: psi_q(b) - psi_q(a) + int w_e psi_d + R int i_q + V_e int e_q = int u_q
    dB = B[b] - B[a]
    dW = W_int[b] - W_int[a]
    rows_d = np.hstack([dB, -dW])
    rows_q = np.hstack([dW, dB])
    A = np.vstack([rows_d, rows_q])
    over_window = lambda x: np.concatenate([x[b, 0] - x[a, 0], x[b, 1] - x[a, 1]])  # noqa: E731
    rhs = over_window(U_int)
    if R is None:
        A = np.hstack([A, over_window(I_int)[:, None]])
    else:
        rhs = rhs - R * over_window(I_int)
    D, centres = _second_differences(n_d, n_q)
    # strong at an unmeasured node, unless one of its two neighbours along the row is measured and the other
    # not: there the map bends as its measured side says (a row of them between two measured rows is
    # interpolated across, not flattened along)
    outer = ((np.abs(D) == 1.0) & measured.ravel()[None, :]).sum(1)
    strong = ~measured.ravel()[centres] & (outer != 1)
    D = D * np.where(strong, UNMEASURED_SMOOTHNESS, 1.0)[:, None]
    n_columns = A.shape[1] + inverter_error
    prior = np.zeros((2 * D.shape[0], n_columns))
    prior[: D.shape[0], :n_nodes] = D
    prior[D.shape[0] :, n_nodes : 2 * n_nodes] = D
    scale = np.sqrt(A.shape[0] / max(prior.shape[0], 1))  # the prior weighs like as many rows as the data
    prior_rhs = np.zeros(len(prior))

    def solve(eps, weight):
        """``(x, A, cost)``: the least-squares solution with the error's sign smoothed over ``eps`` A and
        the prior weighted ``weight``, the window equations' matrix and the sum of squares (prior
        included) at the solution."""
        A_eps = A
        if inverter_error:
            e = _inverter_error_per_volt(i_dq, log.theta_e, eps)
            E_int = cum(half * (e[:-1] + e[1:]))
            A_eps = np.hstack([A, over_window(E_int)[:, None]])
        M = np.vstack([A_eps, weight * scale * prior])
        target = np.concatenate([rhs, prior_rhs])
        x, *_ = np.linalg.lstsq(M, target, rcond=None)
        return x, A_eps, float(np.sum((M @ x - target) ** 2))

    # The least smoothing whose map passes the flux-map checks: a log that walks a grid of operating
    # points determines every node at the first weight; one of ordinary operation follows one path through
    # the current plane, and the interpolant's representation error along it would otherwise tilt the
    # nodes off the path into a map that stores no energy.
    for attempt in range(SMOOTHNESS_STEPS + 1):
        weight = SMOOTHNESS * 2.0**attempt
        eps = error_smoothing_a
        if inverter_error and eps is None:
            eps = _profiled_smoothing(lambda e, w=weight: solve(e, w)[2], i_dq)
        x, A_fit, _ = solve(eps, weight)
        psi_d, psi_q = x[:n_nodes].reshape(n_d, n_q), x[n_nodes : 2 * n_nodes].reshape(n_d, n_q)
        try:
            grid = FluxMapGrid(i_d, i_q, psi_d, psi_q, source="identified flux map")
            break
        except ParameterError as err:
            failure = str(err).split(": ", 1)[1]
    else:
        lo, hi = i_dq.min(axis=0), i_dq.max(axis=0)
        visited = f"i_d {plain(lo[0])} to {plain(hi[0])} A, i_q {plain(lo[1])} to {plain(hi[1])} A"
        reached = f"{int(measured.sum())} of {measured.size} grid points of {plain(h[0])} A"
        raise ParameterError(
            f"{where}: the identified map is not a usable flux map, even smoothed "
            f"{2**SMOOTHNESS_STEPS} times more ({failure} The log's currents reach {reached}, {visited}.) "
            "If its columns are right, the log does not determine the map: walk a grid of (i_d, i_q) "
            "operating points at a held speed, or try another --flux-map-step."
        )
    residual = A_fit @ x - rhs
    k = 2 * n_nodes
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
        smoothness=weight,
    )
