"""snapwarn simulators: normal forms, Euler beam, discrete Cosserat rod (pure numerics)."""
