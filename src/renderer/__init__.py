"""pgi renderer: progressive light transport in participating media."""

import os

# OpenMP workers spin about 10 us after a kernel, then sleep. With OMP_WAIT_POLICY=passive
# (spin 0, the setting before) every kernel after an Embree call woke its workers through the
# kernel's scheduler; libgomp's default 3 ms spin would compete with Embree, which traces from
# Python threads on the same cores right after a kernel. Measured against passive on 2 cores:
# 10-13 % more rays per second in pt (docs/methods.md). libgomp reads this when _core loads;
# a user's own GOMP_SPINCOUNT or OMP_WAIT_POLICY wins.
if "OMP_WAIT_POLICY" not in os.environ and "GOMP_SPINCOUNT" not in os.environ:
    os.environ["GOMP_SPINCOUNT"] = "1000"

__version__ = "0.1.0"
