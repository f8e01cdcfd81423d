"""How a log file is written, from a log config's ``[log]`` table: ``delimiter``, ``header_row``,
``decimal`` ([`pmsmjax.io.csv_dialect`][pmsmjax.io.csv_dialect]) and ``format``, a preset of a tool's log
layout (its delimiter, column names and units) under the user's own ``[columns]`` and ``[units]``.

**``format = "vesc"``**: the CSV that VESC Tool writes when it logs realtime data ("Log RT data"; the
header and row writers are ``VescInterface::openRtLogFile`` and the ``valuesReceived`` handler in
``vescinterface.cpp`` of vedderb/vesc_tool): semicolon separated with a semicolon after the last field,
``ms_today`` the time of day in ms (UTC; it wraps at midnight), ``erpm`` the electrical speed in r/min,
``d_axis_current``, ``q_axis_current`` (A), ``d_axis_voltage``, ``q_axis_voltage`` (V; newer versions),
``input_voltage`` the DC link (V), ``temp_motor`` (degC). Its ``duty_cycle`` is the modulation magnitude,
not phase duties, and ``current_motor`` the current's magnitude: neither is read. VESC Tool logs at its
polling rate (tens of Hz), far slower than identification needs: such a log reads, and ``identify``
then refuses its sampling step; a log of the firmware's sampling at the control rate in this layout is
identified.
"""

from pmsmjax.io.csv_dialect import DELIMITERS, CsvDialect
from pmsmjax.spec.validation import ParameterError

__all__ = ["READER_KEYS", "PRESETS", "PresetColumn", "reader_options"]

#: ``[log]`` keys that say how the file is written (every command that reads a log takes them).
READER_KEYS = ("format", "delimiter", "header_row", "decimal")
#: Log layouts of tools: ``{name: {"delimiter", "columns", "units"}}``.
PRESETS = {
    "vesc": {
        "delimiter": ";",
        "columns": {
            "time": "ms_today",
            "omega_m": "erpm",
            "i_d": "d_axis_current",
            "i_q": "q_axis_current",
            "u_d": "d_axis_voltage",
            "u_q": "q_axis_voltage",
            "U_dc": "input_voltage",
            "temperature_c": "temp_motor",
        },
        "units": {"time": "ms", "omega_m": "erpm"},
    },
}


class PresetColumn(str):
    """A file column name a preset maps a canonical column to: a log without it is read without that
    column (an older version of the tool), where a user's mapping to a missing column is refused."""


def reader_options(log_table: dict, columns: dict, units: dict, source: str = "[log]", readable=None):
    """``(CsvDialect, columns, units)`` from the reader keys of a ``[log]`` table: a preset's column map and
    units (those of the canonical columns in `readable`, when given) under the given `columns` and `units`
    (which win). Refuses an unknown format, delimiter or decimal
    mark and a header row that is not a positive line number, in one line naming the key."""
    table = {k: v for k, v in log_table.items() if k in READER_KEYS}
    preset = {}
    if "format" in table:
        name = table["format"]
        if name not in PRESETS:
            raise ParameterError(
                f"{source} format = {name!r} is not a known log format; known: {', '.join(PRESETS)} (or drop "
                "it and map the columns with [columns])."
            )
        preset = PRESETS[name]
    delimiter = table.get("delimiter", preset.get("delimiter"))
    if delimiter is not None and delimiter not in DELIMITERS:
        raise ParameterError(
            f'{source} delimiter = {delimiter!r}: give one of ",", ";", "tab" or "whitespace" (runs of '
            "spaces)."
        )
    header_row = table.get("header_row")
    if header_row is not None and (
        not isinstance(header_row, int) or isinstance(header_row, bool) or header_row < 1
    ):
        raise ParameterError(
            f"{source} header_row = {header_row!r}: give the 1-based line number of the header row, e.g. 3."
        )
    decimal = table.get("decimal", ".")
    if decimal not in (".", ","):
        raise ParameterError(f'{source} decimal = {decimal!r}: give "." or ",".')
    dialect = CsvDialect(DELIMITERS[delimiter] if delimiter else None, header_row, decimal)
    keep = lambda c: readable is None or c in readable
    preset_columns = {c: PresetColumn(n) for c, n in preset.get("columns", {}).items() if keep(c)}
    preset_units = {c: u for c, u in preset.get("units", {}).items() if keep(c)}
    return dialect, {**preset_columns, **dict(columns or {})}, {**preset_units, **dict(units or {})}
