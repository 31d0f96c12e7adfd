"""jaxmpm's benchmark against reference codes written in NumPy, plain JAX, Taichi and Warp.

Kept beside the package in a source checkout, not installed: ``jaxmpm bench`` runs it from there.
``bench`` is the driver (``bench.run``), ``_baselines`` the 1D reference codes and ``_baselines_2d``
those of 2D and 3D; ``sharded`` times one run spread over several devices.
"""
