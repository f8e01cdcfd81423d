"""pmsmjax/checks/plausibility.py called directly (the commands reach it through tests/cli/test_careless.py):
a
unit
slip in a motor's values is refused in one line that names the field and gives the SI value to write; the book
motor passes."""

import pytest

from pmsmjax.spec.plausibility import check_motor_units
from pmsmjax.spec.validation import ParameterError

BOOK = {"R": 0.958, "L_d": 5.25e-3, "L_q": 12e-3, "psi_f": 0.1827, "J": 0.003, "B": 0.008, "pole_pairs": 4}


def test_book_motor_is_plausible():
    check_motor_units(BOOK, "motor file book.toml", Ts=1e-4)


def test_inductance_given_in_mh_is_refused_with_the_si_value():
    with pytest.raises(ParameterError) as info:
        check_motor_units({**BOOK, "L_d": 5.25}, "motor file m.toml")
    message = str(info.value)
    assert message.startswith("motor file m.toml: L_d = 5.25 H")
    assert "write 0.00525 (H)" in message and "\n" not in message
