"""Simulated devices: physical models behind the same interfaces as the hardware drivers.

Test-only knobs carry a ``sim_`` prefix; each simulator's docstring has a Notes section listing how
it differs from the real device.
"""
