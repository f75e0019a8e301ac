"""One place that initialises Warp for the whole package (quiet, no adjoint code)."""

import os
import sys
import tempfile

import warp as wp

wp.config.log_level = wp.LOG_WARNING  # no greeting or per-module load lines on stdout
# The renderer never differentiates: skipping the adjoint halves compile time and code size.
wp.config.enable_backward = False

NO_DRIVER = "Could not find or load the NVIDIA CUDA driver"


def _init() -> None:
    """wp.init(), minus the native library's notice that this CPU machine has no CUDA driver.

    The renderer runs on the CPU by design, so that notice on every CLI run is noise; anything
    else Warp prints while starting is passed on to stderr unchanged.
    """
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no real stderr (embedded interpreter): nothing to filter
        wp.init()
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        tmp.seek(0)
        for line in tmp.read().decode(errors="replace").splitlines(keepends=True):
            if NO_DRIVER not in line:
                sys.stderr.write(line)


_init()
