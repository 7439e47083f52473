"""pgi renderer: progressive light transport in participating media."""

import os

# OpenMP workers must sleep, not spin, between kernels: Embree traces from
# Python threads on the same cores while they wait. Read when _core loads.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

__version__ = "0.1.0"
