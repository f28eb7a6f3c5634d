"""The runtime: float64 configuration, compilation, the on-disk program store and its
fingerprints, JAX's compilation cache, dispatch and the environment switches."""
