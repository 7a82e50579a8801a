import os

# One OpenBLAS thread, set before NumPy loads (as the CLI does): next to JAX's own threads a
# threaded OpenBLAS oversubscribes a small machine and stalls the fits' small dense solves
# (a structure-estimated fit of the bundled data: 37 s -> 0.7 s steady state at load 4).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "standard")
