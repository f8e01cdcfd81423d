"""The one registry of methods: every control method, estimator, multi-phase modulator and machine frame by
name, with its one-line description, the machines it runs on, the factory that builds it and the options
that factory takes. Plain Python (no JAX): ``pmsmjax --help``, the commands' checks before a run, the
presets, the estimator catalogue, tuning and the documentation all read it, and a method added here is
known to all of them.

A factory is named as ``"module:attribute"`` and imported only when a drive is built
([`load_factory`][pmsmjax.spec.registry.load_factory]), so reading the registry costs nothing. The options a
method takes are declared here, not read from the factory's signature; ``tests/spec/test_registry.py`` checks
that the two agree.
"""

import dataclasses
import difflib
import importlib

from pmsmjax.spec.validation import ParameterError

__all__ = [
    "MACHINES",
    "Method",
    "REGISTRY",
    "method",
    "names",
    "check_name",
    "load_factory",
]

#: The machines a drive can have, by their command-line names, and their phase counts.
MACHINES = {"three-phase": 3, "six-phase": 6, "five-phase": 5}
THREE = ("three-phase",)
MULTIPHASE = ("six-phase", "five-phase")

#: The option groups the drive presets share: the plant (its model frame, mechanics, speed or torque
#: mode); the speed loop, current limit and DC link; the control period and its sub-steps, delay and
#: speed-loop divider.
_PLANT = ("frame", "mechanics", "mode")
_LIMITS = ("speed_bandwidth", "current_limit", "u_dc")
_PERIOD = ("Ts", "n_substeps", "computation_delay", "speed_divider")
#: What every three-phase FOC-type preset takes besides its method's own options.
_FOC_DRIVE = (*_PLANT, "current_bandwidth", *_LIMITS, *_PERIOD, "d_axis")
#: What the comparator drives (hysteresis, table DTC) take besides their own options (their period is the
#: comparator's sample).
_COMPARATOR_DRIVE = (*_PLANT, *_LIMITS, "n_substeps", "computation_delay")
#: What the six- and five-phase drives take.
_MULTIPHASE_DRIVE = (
    "control", "pwm", "bridge", *_PLANT, "current_bandwidth", *_LIMITS, *_PERIOD, "w_c", "dead_time",
    "resistance_scale",
)  # fmt: skip
_SMO = ("switching", "max_speed_rpm", "k_margin", "pole")
_HFI = ("hf_voltage", "hf_frequency", "bandpass_q")


@dataclasses.dataclass(frozen=True)
class Method:
    """One method of the registry.

    Attributes:
        kind: ``"control"``, ``"estimator"``, ``"modulator"`` or ``"frame"``.
        name: its name on the command line and in files (``"smc-dtc"``).
        description: one line for ``--help`` and the documentation.
        machines: the machines it runs on (keys of [`MACHINES`][pmsmjax.spec.registry.MACHINES]).
        factory: ``"module:attribute"`` of what builds it (a preset for a control, a design rule for an
            estimator, a class or function for a modulator or frame).
        options: the keyword options the factory takes.
        fixed: keyword values the registry passes itself (``angle="pll"`` for ``smo-pll``).
        group: a finer kind: ``"observer"`` (chapter 5 back-EMF observers), ``"injection"`` (chapter 6
            HF injection), ``"hybrid"`` for estimators; ``"foc"`` (a FOC cascade, which can run sensorless:
            it holds the I/f start-up current) or ``"comparator"`` (leg states chosen by comparators) or
            ``"direct"`` (SVPWM DTC) for three-phase controls; ``""`` otherwise.
        default: whether it is the default of its kind on its machines.
    """

    kind: str
    name: str
    description: str
    machines: tuple[str, ...]
    factory: str
    options: tuple[str, ...] = ()
    fixed: tuple[tuple[str, object], ...] = ()
    group: str = ""
    default: bool = False


def _control(name, description, factory, options, group, machines=THREE, default=False):
    return Method("control", name, description, machines, factory, options, (), group, default)


def _multiphase_control(machine, name, description, default=False):
    """A control of the six- or five-phase ``machine``: its drive preset builds it."""
    preset = machine.replace("-", "_")
    factory = f"pmsmjax.presets.{preset}:{preset}_drive"
    return _control(name, description, factory, _MULTIPHASE_DRIVE, "", (machine,), default)


def _modulator(machine, name, description, factory, default=False):
    """A modulator of the six- or five-phase ``machine``; a bare `factory` is an attribute of its preset."""
    if ":" not in factory:
        factory = f"pmsmjax.presets.{machine.replace('-', '_')}:{factory}"
    return Method("modulator", name, description, (machine,), factory, default=default)


def _estimator(name, description, factory, options, group, fixed=()):
    return Method("estimator", name, description, THREE, factory, options, fixed, group)


REGISTRY: tuple[Method, ...] = (
    # Three-phase controls (the book, ch. 3 and 4).
    _control(
        "pi",
        "cascaded PI FOC, i_d = 0 (book ch. 3)",
        "pmsmjax.presets.three_phase:book_drive",
        _FOC_DRIVE,
        "foc",
        default=True,
    ),  # fmt: skip
    _control(
        "smc",
        "sliding-mode speed loop, exponential reaching law, dq PI currents (ch. 3)",
        "pmsmjax.presets.three_phase:smc_drive",
        ("switching", "time_constant_s", "reaching_ratio", "load_torque_rate_nm_s", "margin", *_FOC_DRIVE),
        "foc",
    ),
    _control(
        "pr",
        "proportional-resonant current loops in alpha-beta, PI speed loop (ch. 3)",
        "pmsmjax.presets.three_phase:pr_drive",
        ("w_c", "discretisation", "phase_lead", "back_emf_feedforward", *_FOC_DRIVE),
        "foc",
    ),
    _control(
        "hysteresis",
        "hysteresis current comparators, PI speed loop (ch. 3)",
        "pmsmjax.presets.three_phase:hysteresis_drive",
        ("band_a", "sample_period_s", "speed_period_s", *_COMPARATOR_DRIVE, "comparator", "smooth_width_a"),
        "comparator",
    ),
    _control(
        "dtc",
        "switching-table direct torque control, flux observer, PI speed loop (ch. 4)",
        "pmsmjax.presets.three_phase:dtc_drive",
        (
            "sample_period_s",
            "torque_band_nm",
            "flux_band_wb",
            "torque_levels",
            "flux_ref_wb",
            "speed_period_s",
            "crossover_rad_s",
            *_COMPARATOR_DRIVE,
        ),
        "comparator",
    ),  # fmt: skip
    _control(
        "smc-dtc",
        "sliding-mode direct torque control with SVPWM, PI speed loop (ch. 4)",
        "pmsmjax.presets.three_phase:smc_dtc_drive",
        (
            "switching",
            "torque_rate_nm_per_ms",
            "flux_rate_wb_per_s",
            "torque_bandwidth",
            "flux_bandwidth",
            "flux_ref_wb",
            "crossover_rad_s",
            *_PLANT,
            *_LIMITS,
            *_PERIOD,
        ),
        "direct",
    ),  # fmt: skip
    # Six-phase controls (the book, ch. 7-9).
    _multiphase_control(
        "six-phase",
        "vsd",
        "VSD: dq PIs and z1-z2 PIs (counter-rotating frame), PI speed loop (ch. 9)",
        default=True,
    ),
    _multiphase_control(
        "six-phase",
        "double-dq",
        "double dq: four PIs with cross-coupling compensation, PI speed loop (ch. 9)",
    ),
    _multiphase_control(
        "six-phase", "conventional", "dq PIs only, z1-z2 voltage zero (open loop), PI speed loop (ch. 9)"
    ),
    _multiphase_control(
        "six-phase", "pr", "stationary-frame PR on alpha-beta and z1-z2, PI speed loop (ch. 9)"
    ),
    # Five-phase controls (the book, ch. 10).
    _multiphase_control(
        "five-phase",
        "vsd",
        "i_d = 0 vector control: dq PIs and x-y PIs (3 theta_e frame), PI speed loop (ch. 10)",
        default=True,
    ),
    _multiphase_control(
        "five-phase", "conventional", "dq PIs only, x-y voltage zero (open loop), PI speed loop (ch. 10)"
    ),
    _multiphase_control(
        "five-phase",
        "pr",
        "stationary-frame PR on alpha-beta and x-y (resonant at w_e: phase unbalance), PI speed loop",
    ),
    # Estimators: the chapter 5 observers, the chapter 6 HF injection, the whole-speed-range hybrid.
    # The classic SMO's design rule with its two angle extractions: smo (arctan), smo-pll.
    *(
        _estimator(
            name,
            f"classic SMO in alpha-beta, sigmoid switching, back-EMF low-pass, {angle_text} + exact lag "
            "compensation",
            "pmsmjax.estimators.smo:smo_design",
            (*_SMO, "omega_c", "speed_bandwidth", "pll_bandwidth", "emf_floor_fraction", "model"),
            "observer",
            (("angle", angle),),
        )
        for name, angle, angle_text in (("smo", "arctan", "arctan"), ("smo-pll", "pll", "PLL"))
    ),
    _estimator(
        "adaptive-smo",
        "SMO with an adaptive back-EMF model (speed adaptation, no low-pass)",
        "pmsmjax.estimators.adaptive_smo:adaptive_smo_design",
        (*_SMO, "bandwidth", "emf_floor_fraction", "model"),
        "observer",
    ),
    _estimator(
        "dq-smo",
        "SMO in the estimated rotating frame on the extended EMF, PLL on E_d (salient)",
        "pmsmjax.estimators.dq_smo:dq_smo_design",
        (*_SMO, "omega_c", "pll_bandwidth", "emf_floor_fraction", "model"),
        "observer",
    ),
    _estimator(
        "mras",
        "MRAS: current model as adjustable model, Popov PI speed adaptation",
        "pmsmjax.estimators.mras:mras_design",
        ("bandwidth", "model"),
        "observer",
    ),
    _estimator(
        "ekf",
        "extended Kalman filter, state [i_alpha, i_beta, w_e, theta_e]",
        "pmsmjax.estimators.ekf:ekf_design",
        (
            "current_noise_a",
            "voltage_error_v",
            "acceleration_torque_nm",
            "angle_walk_rad",
            "max_speed_rpm",
            "model",
        ),
        "observer",
    ),
    _estimator(
        "flux-observer",
        "reduced-order stator-flux observer on the flux map or linear model, speed-adaptive (Hinkkanen 2018)",
        "pmsmjax.estimators.map_flux_observer:flux_observer_design",
        ("bandwidth", "sigma0", "zeta", "max_speed_rpm", "model", "flux_map"),
        "observer",
    ),
    _estimator(
        "hfi-rotating",
        "rotating HF injection (salient machines, standstill and low speed; angle modulo pi)",
        "pmsmjax.estimators.hfi_rotating:hfi_rotating_design",
        (
            *_HFI,
            "sequence_cutoff",
            "error_cutoff",
            "pll_bandwidth",
            "theta0",
            "delay_periods",
            "carrier",
            "filter_feedback",
        ),
        "injection",
    ),  # fmt: skip
    _estimator(
        "hfi-pulsating",
        "pulsating HF injection on the estimated d axis (salient machines; angle modulo pi)",
        "pmsmjax.estimators.hfi_pulsating:hfi_pulsating_design",
        (*_HFI, "error_cutoff", "pll_bandwidth", "theta0", "delay_periods", "filter_feedback"),
        "injection",
    ),
    _estimator(
        "hybrid",
        "HF injection (with start-up polarity pulses) below a crossover band, EKF above: whole speed range",
        "pmsmjax.estimators.hybrid:hybrid_design",
        (
            "injection",
            "observer",
            "low_rpm",
            "high_rpm",
            "off_rpm",
            "speed_filter",
            "polarity",
            "delay_periods",
            "injection_options",
            "observer_options",
            "polarity_options",
            "injection_motor",
        ),
        "hybrid",
    ),  # fmt: skip
    # Multi-phase modulators (the book, ch. 8 and 10).
    _modulator(
        "six-phase",
        "four-vector",
        "four-vector SVPWM (z1-z2 volt-seconds zero)",
        "_four_vector",
        default=True,
    ),
    _modulator("six-phase", "two-vector", "two-vector SVPWM (largest vectors only)", "_two_vector"),
    _modulator(
        "six-phase",
        "decoupled",
        "two SVPWMs, one per three-phase set",
        "pmsmjax.inverters.decoupled_svpwm:DecoupledSVPWM",
    ),
    _modulator("six-phase", "double-zs", "carrier PWM with a zero sequence per set", "_double_zs"),
    _modulator(
        "five-phase",
        "near-four-vector",
        "near-four-vector SVPWM (x-y volt-seconds zero)",
        "_nfv",
        default=True,
    ),
    _modulator("five-phase", "carrier", "carrier PWM with the min-max zero sequence", "_carrier"),
    _modulator("five-phase", "sinusoidal", "sinusoidal carrier PWM", "_sinusoidal"),
    _modulator("five-phase", "large-vector", "large vectors only (x-y uncontrolled)", "_large"),
    # Machine model frames.
    Method("frame", "dq", "rotor frame", ("three-phase", "six-phase", "five-phase"), "", default=True),
    Method("frame", "alpha_beta", "stationary frame", THREE, ""),
    Method("frame", "abc", "phase quantities", THREE, ""),
    Method("frame", "vsd", "vector space decomposition", MULTIPHASE, ""),
    Method("frame", "double-dq", "two dq frames, one per three-phase set", ("six-phase",), ""),
    Method("frame", "natural", "phase quantities", MULTIPHASE, ""),
)


def names(kind: str, machine: str | None = "three-phase", group: str | None = None) -> tuple[str, ...]:
    """The names of ``kind`` on ``machine`` (None: any machine), optionally of one ``group``, in registry
    order, each once."""
    found = (
        m.name
        for m in REGISTRY
        if m.kind == kind and (machine is None or machine in m.machines) and group in (None, m.group)
    )
    return tuple(dict.fromkeys(found))


def default(kind: str, machine: str = "three-phase") -> str:
    """The default name of ``kind`` on ``machine``."""
    return next(m.name for m in REGISTRY if m.kind == kind and machine in m.machines and m.default)


def check_name(kind: str, name: str, machine: str = "three-phase", what: str | None = None) -> None:
    """Refuse a name ``kind`` does not have on ``machine`` in one line, with the closest known name and the
    machine that has it."""
    known = names(kind, machine)
    if name in known:
        return
    what = what or kind
    elsewhere = [m for m in MACHINES if m != machine and name in names(kind, m)]
    if elsewhere:
        raise ParameterError(
            f"{what} {name!r} runs on the {' or '.join(elsewhere)} machine; on the {machine} machine choose "
            f"from {', '.join(known)}."
        )
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.5)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise ParameterError(f"unknown {what} {name!r}{hint}: choose from {', '.join(known)}.")


def method(kind: str, name: str, machine: str = "three-phase", what: str | None = None) -> Method:
    """The registry entry of ``name`` (refused in one line when unknown on ``machine``)."""
    check_name(kind, name, machine, what)
    return next(m for m in REGISTRY if m.kind == kind and m.name == name and machine in m.machines)


def load_factory(entry: Method):
    """The object ``entry.factory`` names (imports its module: JAX for every factory but the frames')."""
    module, _, attribute = entry.factory.partition(":")
    return getattr(importlib.import_module(module), attribute)


def check_options(entry: Method, options) -> None:
    """Refuse options the method does not take, in one line listing those it does."""
    bad = sorted(set(options) - set(entry.options))
    if bad:
        raise ParameterError(
            f"option(s) {', '.join(bad)} do not apply to {entry.kind} {entry.name!r}; it takes "
            f"{', '.join(entry.options)}."
        )
