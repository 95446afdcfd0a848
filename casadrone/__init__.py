"""casadrone: racing-drone airframe optimisation on CasADi and pymoo.

casadrone's parallelism is one process per core (see ``casadrone.optimise``). Its linear algebra is
on 20×20 matrices, where a multi-threaded BLAS is up to 5× slower than one thread, so the BLAS
thread pools default to one thread unless the user has set them before importing casadrone.
"""

import os as _os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

__version__ = "0.1.0"
