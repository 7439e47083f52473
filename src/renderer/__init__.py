"""pgi renderer: progressive light transport in participating media."""

import os

# OpenMP workers spin about 10 us after a kernel, then sleep. Sleeping at once (passive, spin
# 0) makes every kernel wake its workers through the kernel scheduler; spinning for libgomp's
# default 3 ms competes with Embree, which traces from Python threads on the same cores right
# after a kernel. Measured on 2 cores: 11-17 % more rays per second in pt than either (see
# docs/methods.md). libgomp reads these when _core loads; a user's own setting wins.
if "OMP_WAIT_POLICY" not in os.environ and "GOMP_SPINCOUNT" not in os.environ:
    os.environ["OMP_WAIT_POLICY"] = "passive"
    os.environ["GOMP_SPINCOUNT"] = "1000"

__version__ = "0.1.0"
