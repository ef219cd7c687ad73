"""Problem set-up, SNES solver, load stepping, outputs and the command line.

One BLAS thread per MPI rank (set before numpy or PETSc load BLAS).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
