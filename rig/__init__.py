"""cutlab.rig: hardware and orchestration.

DAQ drivers (NI-DAQmx and simulated), DNC streaming (Fanuc drip feed, GRBL), the HDF5 logger, the
simulated machining rig and the campaign runner. May import ``analysis`` and ``planning``.
"""
