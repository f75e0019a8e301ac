"""How work is cut for a device. The CPU: a Warp CPU launch runs on one thread and releases the GIL,
so parallel work is launched in bands, one Python thread per core. A CUDA device: one launch runs
every item at once, so the work is launched whole (bands would starve the GPU), from one thread.

progressive.py hands bands of pixels to its threads as they come free (with progress after each band);
`BandLauncher` cuts n independent items (the rays of a radiosity shot) into one band per thread.
`check_device` turns a device name from a command line into Warp's, or says which ones there are.
"""

from __future__ import annotations

import argparse
import os
import threading
from concurrent.futures import ThreadPoolExecutor

import warp as wp

from tracer.kernels import wpinit  # noqa: F401  (initialise Warp once, quietly)

ITEMS_PER_BAND = 1024  # fewer than twice this many items run in one band (threads cost more than they save)


class DeviceError(ValueError):
    """A device name that Warp has no device for on this machine."""


def check_device(name: str | None) -> str:
    """Warp's name of the device `name` ("cpu", "cuda:0", ...; "cuda" is the default CUDA device), or
    DeviceError saying which devices this machine has: "warp has no device cuda:0 here; available: cpu"."""
    name = (name or "cpu").strip()
    have = [d.alias for d in wp.get_devices()]
    if name == "cuda" and wp.get_cuda_device_count() > 0:
        name = str(wp.get_device("cuda").alias)  # "cuda:N" (a str: Warp leaves Device.alias unannotated)
    if name not in have:  # never wp.get_device(name) here: on a machine without CUDA that prints driver noise
        raise DeviceError(f"warp has no device {name} here; available: {', '.join(have)}")
    return name


def device_arg(name: str) -> str:
    """The argparse type of a `--device` option: check_device's name, or its message as a usage error
    (exit status 2: "error: argument --device: warp has no device cuda:0 here; available: cpu")."""
    try:
        return check_device(name)
    except DeviceError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def is_cuda(device) -> bool:
    """Whether `device` (a name or a wp.Device) is a CUDA device: whole launches, no thread pool."""
    return wp.get_device(device).is_cuda


def default_threads() -> int:
    """One thread per core."""
    return max(1, os.cpu_count() or 1)


_POOLS: dict[int, ThreadPoolExecutor] = {}
_POOLS_LOCK = threading.Lock()


def thread_pool(threads: int) -> ThreadPoolExecutor:
    """A pool of `threads` threads shared by every render of this process that asks for that many:
    starting threads for each pass of a small render cost more than its launches (2 ms a thread while
    the others run). Renders that share a pool never wait on each other's tasks, so they cannot
    deadlock; at worst they take turns."""
    with _POOLS_LOCK:
        pool = _POOLS.get(threads)
        if pool is None:
            pool = _POOLS[threads] = ThreadPoolExecutor(threads, thread_name_prefix=f"tracer-{threads}")
        return pool


class BandLauncher:
    """Launches a kernel over n items in bands, one band per thread (on a CUDA device: all n in one
    launch); each item writes only its own slot, so results never depend on the threads."""

    def __init__(self, threads: int, device: str):
        self.threads, self.device = max(1, threads), device
        self.pool = thread_pool(self.threads) if self.threads > 1 and not is_cuda(device) else None

    def __call__(self, kernel, n: int, inputs) -> None:
        """inputs(first) -> the kernel's inputs for the band starting at item `first`."""
        bands = self.threads if self.pool and n >= 2 * ITEMS_PER_BAND else 1
        edges = [n * b // bands for b in range(bands + 1)]

        def run(b: int) -> None:
            wp.launch(kernel, dim=edges[b + 1] - edges[b], inputs=inputs(edges[b]), device=self.device)

        if bands == 1:
            run(0)
        else:
            assert self.pool is not None, "more than one band with a pool alone"
            list(self.pool.map(run, range(bands)))
        wp.synchronize_device(self.device)

    def close(self) -> None:
        """Nothing to release: the pool is shared (kept for the callers that say they are done)."""
        self.pool = None
