"""Compiled searches of the predictor (numba ``@njit`` over plain arrays): Brent's steps, the law
kernels, the secondary-fold (conformal) searches and the mu* profile scans."""
