"""A Monte Carlo study's settings from a TOML file (``pmsmjax montecarlo --config FILE``): its tables
``[study]``, ``[drive]``, ``[scenario]``, ``[thresholds]`` and ``[parameters]``, as keyword arguments of
[`Study`][tuning.montecarlo.study.Study]."""

from pathlib import Path

from pmsmjax.io.toml_parser import read_toml
from pmsmjax.spec.validation import ParameterError

__all__ = ["read_study_toml"]

_SECTIONS = {
    "study": ("n", "seed", "sampling", "chunk_size", "nonphysical", "decimate", "sensitivity_runs"),
    "drive": (
        "motor",
        "gains",
        "current_bandwidth",
        "speed_bandwidth",
        "current_limit",
        "u_dc",
        "n_substeps",
        "unroll_substeps",
        "machine",
        "control",
        "pwm",
        "estimator",
    ),
    "scenario": ("speed_rpm", "load_nm", "load_time_s", "duration_s"),
    "thresholds": ("current_a", "tracking_rpm"),
}


def read_study_toml(path) -> dict:
    """Study settings from a TOML file as keyword arguments of [`Study`][tuning.montecarlo.study.Study]
    (checked by it)."""
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"study file {path} does not exist: check the path.")
    data = read_toml(path, f"study file {path}")
    unknown = sorted(set(data) - set(_SECTIONS) - {"parameters"})
    if unknown:
        raise ParameterError(
            f"study file {path}: unknown tables {unknown}; allowed: {sorted(_SECTIONS)} and parameters."
        )
    kwargs = {}
    for section, keys in _SECTIONS.items():
        table = data.get(section, {})
        bad = sorted(set(table) - set(keys))
        if bad:
            raise ParameterError(
                f"study file {path}: unknown keys {bad} in [{section}]; allowed: {', '.join(keys)}."
            )
        for k, v in table.items():
            name = {"current_a": "current_threshold_a", "tracking_rpm": "tracking_threshold_rpm"}.get(k, k)
            kwargs[name] = v
    if "gains" in kwargs:
        gains = Path(kwargs["gains"])
        kwargs["gains"] = str(gains if gains.is_absolute() else path.parent / gains)
    if "parameters" in data:
        kwargs["parameters"] = {
            k: dict(v) if isinstance(v, dict) else v for k, v in data["parameters"].items()
        }
    return kwargs
