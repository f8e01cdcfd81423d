"""The XLA:CPU setting pmsmjax requests on import (pmsmjax/xla_cpu.py): added once, never over a user's own
choice, and in effect: the flux-map plant's sub-step loop compiles into one kernel, and a run computes the
same numbers with it as without."""

import os
import subprocess
import sys

import numpy as np
import pytest

import pmsmjax  # noqa: F401  (the import requests the setting)
from pmsmjax.xla_cpu import SMALL_LOOP_BYTES, request_small_loop_kernels


def test_the_limit_is_added_to_existing_flags():
    environ = {"XLA_FLAGS": "--xla_force_host_platform_device_count=4"}
    assert request_small_loop_kernels(environ)
    assert environ["XLA_FLAGS"] == (
        "--xla_force_host_platform_device_count=4 "
        f"--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES}"
    )
    assert not request_small_loop_kernels(environ)  # once only


def test_a_users_own_limit_is_kept():
    own = "--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=0"
    environ = {"XLA_FLAGS": own}
    assert not request_small_loop_kernels(environ)
    assert environ["XLA_FLAGS"] == own
    environ = {}
    assert request_small_loop_kernels(environ)
    assert environ["XLA_FLAGS"].startswith("--xla_backend_extra_options=")


def test_the_limit_joins_a_users_other_backend_options():
    environ = {"XLA_FLAGS": "--xla_backend_extra_options=xla_cpu_use_fusion_emitters=false --xla_dump_to=/d"}
    assert request_small_loop_kernels(environ)
    assert environ["XLA_FLAGS"] == (
        "--xla_backend_extra_options=xla_cpu_use_fusion_emitters=false,"
        f"xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES} --xla_dump_to=/d"
    )
    assert not request_small_loop_kernels(environ)  # once only


def test_the_merged_options_reach_xla(tmp_path):
    # A fresh interpreter, since XLA_FLAGS is read by the process that compiles: a user's other option
    # and the added limit both parse, and the limit still makes the plant's loop one kernel.
    script = (
        "import jax, jax.numpy as jnp, pmsmjax, os\n"
        "body = lambda i, x: x * 1.0001 + jnp.sin(x)\n"
        "f = jax.jit(lambda x: jax.lax.fori_loop(0, 10, body, x))\n"
        "text = f.lower(jnp.ones(300_000, jnp.float32)).compile().as_text()\n"
        "print(os.environ['XLA_FLAGS'], 'xla_cpu_small_call=\"true\"' in text)\n"
    )
    env = {**os.environ, "XLA_FLAGS": "--xla_backend_extra_options=xla_cpu_use_thunk_runtime=true"}
    r = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip().endswith("True"), r.stdout


#: The XLA option that switches small-loop kernels off (XLA:CPU's default loop emission).
WITHOUT_SMALL_LOOPS = "--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=0"


def _users_environment() -> dict:
    """The environment as a user's command runs: without an XLA option of the caller's."""
    env = dict(os.environ)
    env.pop("XLA_FLAGS", None)
    return env


def _run(script: str, env: dict) -> str:
    r = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout


def test_the_flux_map_plants_loop_compiles_into_one_kernel():
    # XLA's default limit (1 kB) leaves this loop to the per-kernel runtime; the requested one makes it a
    # single kernel (in a fresh interpreter, as a user's command runs).
    script = (
        "import jax, jax.numpy as jnp\n"
        "from pmsmjax.assemble import spec_drive\n"
        "from pmsmjax.io.drive_files import drive_spec\n"
        "from pmsmjax.machines import MachineInput, advance\n"
        "machine = spec_drive(drive_spec('saturated-ipm')).machine\n"
        "def period(machine, state, u):\n"
        "    return advance(machine, state, MachineInput(u, jnp.zeros_like(u[0])), 1e-4, 10)\n"
        "state = machine.initial_state((0.0, 0.0), 100.0, 0.0)\n"
        "u = jnp.asarray([10.0, 50.0], state.currents.dtype)\n"
        "text = jax.jit(period).lower(machine, state, u).compile().as_text()\n"
        "print(type(machine).__name__, 'xla_cpu_small_call=\"true\"' in text)\n"
    )
    assert _run(script, _users_environment()).split() == ["PMSMFluxMapdq", "True"]


@pytest.mark.slow
def test_a_run_computes_the_same_with_and_without_small_loop_kernels():
    """With small-loop kernels (as users run) and without them (XLA's default), the book drive's trace is the
    same to rounding: the option changes how XLA executes a loop, not what it computes."""
    script = (
        "import jax, numpy as np\n"
        "jax.config.update('jax_enable_x64', True)\n"
        "from pmsmjax import presets\n"
        "from pmsmjax.simulate import simulate\n"
        "trace = simulate(presets.book_drive(), presets.book_scenario(duration_s=0.05, load_time_s=0.02))\n"
        "print(' '.join(repr(float(x)) for x in np.asarray(trace.i_dq).ravel()[::97]))\n"
        "print(repr(float(np.asarray(trace.omega_m)[-1])))\n"
    )
    with_kernels = _run(script, _users_environment()).split()
    without = _run(script, {**_users_environment(), "XLA_FLAGS": WITHOUT_SMALL_LOOPS}).split()
    assert len(with_kernels) == len(without) > 10
    np.testing.assert_allclose(np.array(with_kernels, float), np.array(without, float), rtol=1e-9, atol=1e-9)
