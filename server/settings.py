"""Settings in one place: command line, then environment (TRACER_*), then defaults."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from tracer.scene import Limits


def _env(name: str, default, cast=str):
    v = os.environ.get(f"TRACER_{name.upper()}")
    return default if v is None else cast(v)


@dataclass
class Settings:
    host: str = field(default_factory=lambda: _env("host", "127.0.0.1"))
    port: int = field(default_factory=lambda: _env("port", 8000, int))
    data_dir: Path = field(default_factory=lambda: Path(_env("data_dir", "data")))
    preview_size: int = field(default_factory=lambda: _env("preview_size", 160, int))  # example thumbnails, pixels
    max_body_bytes: int = field(default_factory=lambda: _env("max_body_bytes", 2_000_000, int))
    limits: Limits = field(
        default_factory=lambda: Limits(
            max_width=_env("max_width", 2048, int),
            max_height=_env("max_height", 2048, int),
            max_pixels=_env("max_pixels", 2048 * 2048, int),
            max_spp=_env("max_spp", 4096, int),
            max_depth=_env("max_depth", 64, int),
            max_light_samples=_env("max_light_samples", 256, int),
            max_primitives=_env("max_primitives", 2_000_000, int),
        )
    )
