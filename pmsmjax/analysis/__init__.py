"""Figures of merit of drive runs, each defined once: step-response and load metrics, spectra and THD,
observer errors, operating-point checks, the trajectory inside control periods, and gradients of
closed-loop objectives.
"""
