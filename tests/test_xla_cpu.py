"""The XLA:CPU setting pmsmjax requests on import (pmsmjax/xla_cpu.py): added once, never over a user's own
choice, and in effect: the flux-map plant's sub-step loop compiles into one kernel."""

import os
import subprocess
import sys

import jax
import jax.numpy as jnp

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


def test_the_flux_map_plants_loop_compiles_into_one_kernel():
    # XLA's default limit (1 kB) leaves this loop to the per-kernel runtime (checked by hand with the
    # limit set back to 1024 in XLA_FLAGS); the requested one makes it a single kernel.
    if jax.default_backend() != "cpu":
        return
    from pmsmjax.assemble import spec_drive
    from pmsmjax.io.drive_files import drive_spec
    from pmsmjax.machines import MachineInput, advance

    machine = spec_drive(drive_spec("saturated-ipm")).machine
    assert type(machine).__name__ == "PMSMFluxMapdq"

    def period(machine, state, u):
        return advance(machine, state, MachineInput(u, jnp.zeros_like(u[0])), 1e-4, 10)

    state = machine.initial_state((0.0, 0.0), 100.0, 0.0)
    u = jnp.asarray([10.0, 50.0], state.currents.dtype)
    compiled = jax.jit(period).lower(machine, state, u).compile().as_text()
    assert 'xla_cpu_small_call="true"' in compiled
