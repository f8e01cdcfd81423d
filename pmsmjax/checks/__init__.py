"""Checks of user input made before anything compiles: parameter validation and unit plausibility."""
