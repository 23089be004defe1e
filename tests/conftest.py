"""Tests run in 64-bit floats with strict dtype promotion; the library itself never sets this."""

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "standard")
