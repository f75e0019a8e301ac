"""Probe pixels: where a student's image differs most from the reference, one per distinct region of the error
map, so that a student logs the ray trees of their own tracer there (docs/own-tracer.md).

The error is FLIP's per-pixel error (0: the same to the eye, 1: as different as can be). A pixel is in error
when its FLIP error is at least THRESHOLD and at least a quarter of the image's largest error (so a few bright
pixels of a mostly right image are the probes, and faint noise is never one). The pixels in error fall into
regions (8-connected); each region's probe is its pixel of largest error, and the regions are ranked by their
summed error, so one large wrong area outranks a thin edge. An assignment's spec may list probes of its own
(`reference.probes`), which come first.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

MAX_PROBES = 8  # probes from the error map (the spec's own come on top)
THRESHOLD = 0.1  # FLIP error below this is never a probe's reason


@dataclass(frozen=True)
class Probe:
    x: int  # column, from the left
    y: int  # row, from the top
    why: str  # why it was chosen, in words
    error: float | None = None  # FLIP error at the pixel
    region: int | None = None  # pixels of its region

    def to_json(self) -> dict:
        out: dict = {"x": self.x, "y": self.y, "why": self.why}
        if self.error is not None:
            out.update(error=round(self.error, 4), region=self.region)
        return out


def flip_error(reference: np.ndarray, test: np.ndarray) -> np.ndarray:
    """FLIP's per-pixel error (H, W) of two displayed images (floats in [0, 1], sRGB)."""
    import contextlib
    import io

    import flip_evaluator

    with contextlib.redirect_stdout(io.StringIO()):
        err, _, _ = flip_evaluator.evaluate(
            np.ascontiguousarray(reference, dtype=np.float32),
            np.ascontiguousarray(test, dtype=np.float32),
            "LDR", inputsRGB=True, applyMagma=False, computeMeanError=False, parameters={"ppd": 67.0},
        )  # fmt: skip
    err = np.asarray(err, dtype=np.float32)
    return err.reshape(err.shape[0], err.shape[1], -1)[..., 0] if err.ndim == 3 else err


def find(error: np.ndarray, listed: list[dict] | None = None, n: int = MAX_PROBES) -> list[Probe]:
    """The probes of an (H, W) error map: the spec's `listed` ones ({x, y, why?}) first, then one per region of
    the map's largest errors, at most `n` of those."""
    from scipy import ndimage

    out = [Probe(int(p["x"]), int(p["y"]), p.get("why") or "listed by the assignment") for p in listed or ()]
    taken = {(p.x, p.y) for p in out}
    peak = float(error.max()) if error.size else 0.0
    if peak < THRESHOLD:
        return out
    mask = error >= max(THRESHOLD, 0.25 * peak)
    # with no output array, label returns (labels, count): scipy's code returns count alone otherwise
    labels, count = cast(tuple[np.ndarray, int], ndimage.label(mask, structure=np.ones((3, 3), dtype=bool)))
    index = np.arange(1, count + 1)
    sums = ndimage.sum_labels(error, labels, index)
    sizes = ndimage.sum_labels(np.ones_like(error), labels, index)
    places = ndimage.maximum_position(error, labels, index)
    order = sorted(range(count), key=lambda i: (-sums[i], places[i]))
    found: list[Probe] = []
    for rank, i in enumerate(order[:n]):
        y, x = (int(v) for v in places[i])
        e, size = float(error[y, x]), int(sizes[i])
        which = "largest region" if rank == 0 else f"region {rank + 1} of {min(count, n)}, by summed error,"
        why = f"the error map's {which} ({size} pixel{'s' if size != 1 else ''}): FLIP error {e:.2f} here"
        found.append(Probe(x, y, why, e, size))
    # fewer regions than probes: more places in the large regions, each apart from every probe taken
    apart = max(3, min(error.shape) // 6)
    spots = np.argwhere(mask)
    if len(found) < n and len(spots):
        values = error[mask]
        for j in np.argsort(-values, kind="stable"):
            if len(found) >= n:
                break
            y, x = (int(v) for v in spots[j])
            if all(max(abs(x - p.x), abs(y - p.y)) >= apart for p in found):
                size = int(sizes[labels[y, x] - 1])
                why = f"another place in a region of the error map ({size} pixels): FLIP error {error[y, x]:.2f} here"
                found.append(Probe(x, y, why, float(error[y, x]), size))
    out += [p for p in found if (p.x, p.y) not in taken]
    return out
