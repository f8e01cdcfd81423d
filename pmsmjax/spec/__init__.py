"""The drive spec: a drive file's tables as typed, frozen values, with their schema, defaults, derivations,
plausibility checks and the design rules, in plain Python (no JAX), so that every command checks and
derives a drive before anything compiles; and the one registry of methods."""
