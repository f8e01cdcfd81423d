"""pmsmjax/presets/book_constants.py against docs/book_reference.md ("Reference motor and scenario",
chapter 3): the table's values and the derived figures printed under it, written out here; every preset and
the command line's motor values take them from that one module, which loads without JAX."""

import math
import subprocess
import sys

import pytest

from pmsmjax.io.motor_files import motor_values
from pmsmjax.presets import book_constants as book

#: docs/book_reference.md's table, SI units.
TABLE = dict(R=0.958, L_d=5.25e-3, L_q=5.25e-3, psi_f=0.1827, pole_pairs=4, J=0.003, B=0.008)


def test_motor_is_the_books_table():
    assert dict(book.BOOK_MOTOR) == TABLE
    assert dict(book.BOOK_SALIENT_MOTOR) == {**TABLE, "L_q": 12e-3}


def test_drive_and_scenario_are_the_books():
    assert book.BOOK_DC_LINK == 311.0  # V
    assert 1.0 / book.BOOK_TS == pytest.approx(10e3, rel=1e-12)  # 10 kHz PWM and control
    assert book.BOOK_CURRENT_BANDWIDTH == 1100.0  # a_c, rad/s (chapter 3: "reproductions use")
    assert book.BOOK_SPEED_BANDWIDTH == 50.0  # beta, rad/s (chapter 3)
    scenario = (book.BOOK_SPEED_STEP_RPM, book.BOOK_LOAD_NM, book.BOOK_LOAD_TIME_S, book.BOOK_DURATION_S)
    assert scenario == (1000.0, 10.0, 0.2, 0.4)


def test_derived_figures_printed_in_the_book():
    """Torque constant 1.0962 N m/A, 9.12 A for 10 N m, 418.9 rad/s electrical and a 76.5 V back-EMF peak
    at 1000 r/min, L/R = 5.48 ms (to the printed digits)."""
    k_t = 1.5 * book.BOOK_POLE_PAIRS * book.BOOK_PSI_F_WB
    w_e = book.BOOK_POLE_PAIRS * book.BOOK_SPEED_STEP_RPM * 2.0 * math.pi / 60.0
    assert round(k_t, 4) == 1.0962
    assert round(book.BOOK_LOAD_NM / k_t, 2) == 9.12
    assert round(w_e, 1) == 418.9
    assert round(w_e * book.BOOK_PSI_F_WB, 1) == 76.5
    assert round(book.BOOK_L_H / book.BOOK_R_OHM * 1e3, 2) == 5.48
    # The 15 A limit leaves the design-rule step linear (Kp_w 104.7 rad/s = 14.3 A) and covers the load.
    kp_w = book.BOOK_SPEED_BANDWIDTH * book.BOOK_J_KG_M2 / k_t
    assert kp_w * book.BOOK_SPEED_STEP_RPM * math.pi / 30.0 < book.BOOK_CURRENT_LIMIT


def test_read_only():
    with pytest.raises(TypeError):
        book.BOOK_MOTOR["R"] = 1.0


def test_presets_and_motor_values_take_them_from_here():
    from pmsmjax import presets

    for name, salient in (("book", False), ("book_salient", True)):
        motor = presets.book_motor(salient)
        expected = book.BOOK_SALIENT_MOTOR if salient else book.BOOK_MOTOR
        assert {f: float(getattr(motor, f)) for f in expected} == dict(expected)
        assert motor_values(name) == dict(expected)


def test_reading_them_does_not_load_jax():
    code = (
        "import sys\nfrom pmsmjax.presets.book_constants import BOOK_MOTOR\n"
        "assert 'jax' not in sys.modules, sorted(m for m in sys.modules if 'jax' in m)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr
