"""Compiled searches of the predictor (numba ``@njit`` over plain arrays): Brent's steps, the law
kernels, the secondary-fold (conformal) searches and the mu* profile scans."""

from service.analysis._numba_load import install as _fast_cache_load

_fast_cache_load()  # cached kernels load with numba's runtime only (see that module)
