"""Work for the CPU's cores: a Warp CPU launch runs on one thread and releases the GIL, so parallel
work is launched in bands, one Python thread per core.

render.py hands bands of pixels to its threads as they come free (with progress after each band);
`BandLauncher` cuts n independent items (the rays of a radiosity shot) into one band per thread.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import warp as wp

ITEMS_PER_BAND = 1024  # fewer than twice this many items run in one band (threads cost more than they save)


def default_threads() -> int:
    """One thread per core."""
    return max(1, os.cpu_count() or 1)


class BandLauncher:
    """Launches a kernel over n items in bands, one band per thread; each item writes only its own
    slot, so results never depend on the threads."""

    def __init__(self, threads: int, device: str):
        self.threads, self.device = max(1, threads), device
        self.pool = ThreadPoolExecutor(self.threads) if self.threads > 1 and device == "cpu" else None

    def __call__(self, kernel, n: int, inputs) -> None:
        """inputs(first) -> the kernel's inputs for the band starting at item `first`."""
        bands = self.threads if self.pool and n >= 2 * ITEMS_PER_BAND else 1
        edges = [n * b // bands for b in range(bands + 1)]

        def run(b: int) -> None:
            wp.launch(kernel, dim=edges[b + 1] - edges[b], inputs=inputs(edges[b]), device=self.device)

        if bands == 1:
            run(0)
        else:
            list(self.pool.map(run, range(bands)))
        wp.synchronize_device(self.device)

    def close(self) -> None:
        if self.pool:
            self.pool.shutdown()
