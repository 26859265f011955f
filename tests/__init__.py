"""The test suite. Its workers (pytest-xdist) use one BLAS thread each."""

import os

# Two test workers on two cores, each with a multithreaded BLAS, oversubscribe the machine:
# the circuit's many small least-squares solves ran several times slower. Set before numpy loads.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
