"""The XLA:CPU setting pmsmjax requests on import (pmsmjax/xla_cpu.py): added once, never over a user's own
choice, and in effect: the flux-map plant's sub-step loop compiles into one kernel."""

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


def test_a_users_own_backend_options_are_kept():
    own = "--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=0"
    environ = {"XLA_FLAGS": own}
    assert not request_small_loop_kernels(environ)
    assert environ["XLA_FLAGS"] == own
    environ = {}
    assert request_small_loop_kernels(environ)
    assert environ["XLA_FLAGS"].startswith("--xla_backend_extra_options=")


def test_the_flux_map_plants_loop_compiles_into_one_kernel():
    # XLA's default limit (1 kB) leaves this loop to the per-kernel runtime (checked by hand with the
    # limit set back to 1024 in XLA_FLAGS); the requested one makes it a single kernel.
    if jax.default_backend() != "cpu":
        return
    from pmsmjax.io.drive_files import drive_spec
    from pmsmjax.machines import MachineInput, advance
    from pmsmjax.presets.user_drive import spec_drive

    machine = spec_drive(drive_spec("saturated-ipm")).machine
    assert type(machine).__name__ == "PMSMFluxMapdq"

    def period(machine, state, u):
        return advance(machine, state, MachineInput(u, jnp.zeros_like(u[0])), 1e-4, 10)

    state = machine.initial_state((0.0, 0.0), 100.0, 0.0)
    u = jnp.asarray([10.0, 50.0], state.currents.dtype)
    compiled = jax.jit(period).lower(machine, state, u).compile().as_text()
    assert 'xla_cpu_small_call="true"' in compiled
