"""Flux maps as other tools write them, each read into the same
[`FluxMapGrid`][pmsmjax.machines.flux_map.FluxMapGrid] (pmsmjax's convention: d axis along the magnet,
amplitude-invariant dq, currents in A peak, flux linkages in Wb peak per phase, rows along i_d).

Chosen by ``[motor] flux_map_format`` in the drive file, or, without it, by the file's extension and
content ([`pmsmjax.io.flux_map_files.read_flux_map`][pmsmjax.io.flux_map_files.read_flux_map]):

- ``"grid"``: pmsmjax's own layout (CSV ``i_d,i_q,psi_d,psi_q[,measured]``; NPZ/MAT ``i_d, i_q, psi_d,
  psi_q``); NaN fluxes are holes, filled and marked not measured
  ([`scattered`][pmsmjax.io.flux_map_formats.scattered]);
- ``"points"``: scattered operating points, the same four columns (CSV) or 1-D arrays (NPZ/MAT) in any
  places, interpolated onto a grid ([`scattered`][pmsmjax.io.flux_map_formats.scattered]); never chosen
  without the key (a grid CSV with a missing row is refused instead, not silently interpolated);
- ``"syre"``: SyR-e's ``.mat`` (``Id, Iq, Fd, Fq``; its SR axes converted, half a q axis mirrored:
  [`syre`][pmsmjax.io.flux_map_formats.syre]); chosen for a ``.mat`` holding those;
- ``"inductance"``: ``L_d(i_d, i_q)``, ``L_q(i_d, i_q)`` tables and ``psi_m`` (secant inductances:
  [`inductance_tables`][pmsmjax.io.flux_map_formats.inductance_tables]); chosen for a file with ``L_d``
  and ``L_q``;
- ``"motulator"``: complex ``i_s_dq``, ``psi_s_dq`` arrays
  ([`motulator`][pmsmjax.io.flux_map_formats.motulator]); chosen for a file holding those.
"""

__all__ = ["FORMATS"]

#: The values of ``[motor] flux_map_format`` and what each reads.
FORMATS = {
    "grid": "pmsmjax's grid (CSV i_d,i_q,psi_d,psi_q; NPZ/MAT arrays), NaN holes filled",
    "points": "scattered (i_d, i_q, psi_d, psi_q) points, interpolated onto a grid",
    "syre": "SyR-e .mat (Id, Iq, Fd, Fq), SR axes converted, half a q axis mirrored",
    "inductance": "secant L_d(i_d, i_q), L_q(i_d, i_q) tables and psi_m",
    "motulator": "motulator's complex i_s_dq, psi_s_dq arrays",
}
