"""One place that initialises Warp for the whole package (quiet, no adjoint code)."""

import warp as wp

wp.config.log_level = wp.LOG_WARNING  # no greeting or per-module load lines on stdout
# The renderer never differentiates: skipping the adjoint halves compile time and code size.
wp.config.enable_backward = False
wp.init()
