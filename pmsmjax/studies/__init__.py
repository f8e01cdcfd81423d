"""Studies built on the engine: side-by-side comparisons of control methods, observers and PWM, replay
of logged voltages, observers run offline on logs, and the synthetic logs they are tested on.
"""
