"""Regenerate the example assets (run once; the outputs are committed).

python scenes/assets/make_assets.py
"""

from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

HERE = Path(__file__).resolve().parent


def uv_grid(size: int = 256) -> Image.Image:
    """A colourful uv test card: hue across u, brightness up v, a dark grid every 1/8."""
    u, v = np.meshgrid(np.linspace(0, 1, size), np.linspace(1, 0, size))
    r = 0.5 + 0.5 * np.cos(2 * np.pi * (u + 0.0))
    g = 0.5 + 0.5 * np.cos(2 * np.pi * (u + 1 / 3))
    b = 0.5 + 0.5 * np.cos(2 * np.pi * (u + 2 / 3))
    img = np.stack([r, g, b], -1) * (0.35 + 0.65 * v[..., None])
    line = ((u * 8) % 1 < 0.06) | ((v * 8) % 1 < 0.06)
    img[line] = 0.05
    return Image.fromarray((img * 255).astype(np.uint8), "RGB")


def bricks(size: int = 256) -> Image.Image:
    """Height map of bricks: raised bricks with bevelled edges, low mortar (for the image bump map)."""
    y, x = np.mgrid[0:size, 0:size] / size
    row = np.floor(y * 8)
    fy = (y * 8) % 1  # position inside a course of bricks, 0..1
    fx = (x * 4 + 0.5 * (row % 2)) % 1  # position along a brick, 0..1
    # distance to the nearest mortar line, in units of the course height
    dist = np.minimum(np.minimum(fy, 1 - fy), np.minimum(fx, 1 - fx) * 2)
    h = np.clip((dist - 0.05) / 0.15, 0.0, 1.0)
    return Image.fromarray((h * 255).astype(np.uint8), "L")


if __name__ == "__main__":
    uv_grid().save(HERE / "uv_grid.png")
    bricks().save(HERE / "bricks.png")
    torus = trimesh.creation.torus(major_radius=0.7, minor_radius=0.28, major_sections=48, minor_sections=24)
    torus.export(HERE / "torus.obj")
    ico = trimesh.creation.icosphere(subdivisions=1, radius=0.8)
    ico.export(HERE / "icosahedron.ply")
