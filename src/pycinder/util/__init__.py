"""The bottom of the package: helpers every layer may use and that import nothing of pycinder's
own (counts written for people, optional dependencies, the host's worker threads, quiet native
probes)."""
