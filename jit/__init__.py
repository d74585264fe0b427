"""numba for pefsim: kernels compiled on first use, cached on disk, never stale (:mod:`jit.compiled`)."""
