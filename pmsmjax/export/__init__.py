"""A built drive's controller written out for firmware (``pmsmjax export``).

Three steps, one module each:

- [`pmsmjax.export.build`][pmsmjax.export.build]: the drive file -> the drive, as ``pmsmjax demo`` builds it,
  with the gains of a gains file;
- [`pmsmjax.export.description`][pmsmjax.export.description]: a built
  [`Drive`][pmsmjax.drive.Drive] (its design-rule or tuned gains in place) -> a
  [`ControllerDescription`][pmsmjax.export.description.ControllerDescription], plain float32 numbers and the
  static choices of the cascade; a controller export cannot reproduce is refused in one line;
- [`pmsmjax.export.c_source`][pmsmjax.export.c_source]: the description -> a self-contained C99 controller
  (``pmsm_controller.h``, ``pmsm_controller.c``), float32, the same operations in the same order as the
  simulator's controller step, whose code blocks are in
  [`pmsmjax.export.c_blocks`][pmsmjax.export.c_blocks].

The vendor targets write the same description's gains in a firmware's own parameter names and units:
[`pmsmjax.export.odrive`][pmsmjax.export.odrive] (ODrive 0.5.x, ``--target odrive``) and
[`pmsmjax.export.simplefoc`][pmsmjax.export.simplefoc] (SimpleFOC, ``--target simplefoc``),
[`pmsmjax.export.vesc`][pmsmjax.export.vesc] (VESC mcconf, ``--target vesc``) and
[`pmsmjax.export.ti`][pmsmjax.export.ti] (TI MotorControl SDK universal lab, ``--target ti``), with what
they share in
[`pmsmjax.export.vendor_gains`][pmsmjax.export.vendor_gains].

``--target c --fixed-point q15 | q31`` writes the i_d = 0 cascade in integer arithmetic, per unit:
[`pmsmjax.export.fixed_point`][pmsmjax.export.fixed_point] (bases, words, constants, the error bound) and
[`pmsmjax.export.c_fixed_source`][pmsmjax.export.c_fixed_source] (the C).
"""
