"""Unit conversions for the user interface (the library itself works in SI units)."""

import math

RAD_S_PER_RPM = 2.0 * math.pi / 60.0


def rpm_to_rad_s(speed_rpm):
    """Mechanical speed, r/min -> rad/s."""
    return speed_rpm * RAD_S_PER_RPM


def rad_s_to_rpm(speed_rad_s):
    """Mechanical speed, rad/s -> r/min."""
    return speed_rad_s / RAD_S_PER_RPM


#: 0 degC in kelvin.
CELSIUS_K = 273.15


def celsius_to_kelvin(temperature_c):
    """Temperature, degC -> K."""
    return temperature_c + CELSIUS_K


def kelvin_to_celsius(temperature_k):
    """Temperature, K -> degC."""
    return temperature_k - CELSIUS_K
