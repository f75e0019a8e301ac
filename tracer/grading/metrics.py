"""Image comparison that is fair to Monte Carlo noise.

- FLIP (Andersson et al. 2020, `flip-evaluator`), SSIM (Wang et al. 2004) and PSNR (`scikit-image`)
  on the displayed images (exposure, clamp, sRGB), and
- a per-pixel z test of the submission's linear radiance against the reference mean, with the
  variance of both estimates: z = (x - mu) / sqrt(var_x / n_x + var_ref / n_ref + q^2), per channel;
  a pixel is rejected when its largest |z| passes the two-sided critical value for `alpha` (split
  over the three channels). A correct render rejects about `alpha` of its pixels whatever its spp;
  a wrong one rejects whole regions. q is the rounding of the submission's storage (`Encoding`):
  half a step of an 8- or 16-bit PNG, half a unit in the last place of a half-float EXR, else 0.

Each kind of image is compared in the units it holds (`Encoding`): a render or an EXR as linear
radiance against the reference's linear mean; a PNG as clamp(2^exposure L) (its sRGB values decoded)
against the reference mean put through the same exposure and clamp. FLIP, SSIM and PSNR always see
displayed images. The noise baseline is stored the way the submission was (`Encoding.store`), so
both carry the same rounding.

FLIP calls sys.exit() on bad input (and prints): `flip()` turns that into a GradingError.
"""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from statistics import NormalDist
from typing import cast

import numpy as np

from tracer.rendering.film import srgb_encode

PSNR_CAP = 100.0  # dB reported for identical images (PSNR is infinite there)
FLOOR = 1e-4  # smallest standard deviation of a pixel difference (float noise of linear radiance)


class GradingError(Exception):
    """A comparison that cannot be made (sizes differ, a broken image, FLIP refused the input)."""


def display(linear: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """Linear radiance -> what the PNG shows, as floats in [0, 1]: sRGB(clamp(2^exposure L))."""
    return srgb_encode(np.nan_to_num(linear, nan=0.0, posinf=1.0, neginf=0.0) * 2.0**exposure).astype(np.float32)


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """The inverse of the sRGB OETF, values in [0, 1]."""
    c = np.clip(encoded, 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def same_size(reference: np.ndarray, test: np.ndarray) -> None:
    if reference.shape != test.shape:
        rh, rw = reference.shape[:2]
        th, tw = test.shape[:2]
        raise GradingError(f"the image is {tw}x{th} pixels; the reference is {rw}x{rh}")


def flip(reference: np.ndarray, test: np.ndarray, ppd: float = 67.0) -> tuple[float, np.ndarray]:
    """Mean LDR-FLIP error of two displayed images (floats in [0, 1]) and its error map in FLIP's magma
    colours ((H, W, 3) floats in [0, 1]: black no error, through purple and orange, to white);
    `ppd`: pixels per degree of visual angle (FLIP's default, a 0.7 m view of a 4K 27" screen)."""
    import flip_evaluator

    same_size(reference, test)
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said):
            err, mean, _ = flip_evaluator.evaluate(
                np.ascontiguousarray(reference, dtype=np.float32),
                np.ascontiguousarray(test, dtype=np.float32),
                "LDR", inputsRGB=True, applyMagma=True, computeMeanError=True, parameters={"ppd": ppd},
            )  # fmt: skip
    except SystemExit:
        reason = said.getvalue().replace("Exiting.", "").strip() or "no reason given"
        raise GradingError(f"FLIP refused the images: {reason}") from None
    except (RuntimeError, ValueError) as e:
        raise GradingError(f"FLIP failed: {e}") from None
    return float(mean), np.asarray(err, dtype=np.float32).reshape(reference.shape)


def ssim(reference: np.ndarray, test: np.ndarray) -> float:
    """Structural similarity of two displayed images (1 = the same)."""
    from skimage.metrics import structural_similarity

    same_size(reference, test)
    side = min(reference.shape[:2])
    win = min(7, side if side % 2 else side - 1)
    if win < 3:
        raise GradingError(f"the images are too small for SSIM ({side} pixels; at least 3)")
    # without full= or gradient=, the mean similarity alone (skimage's annotation allows the tuples too)
    return float(cast(float, structural_similarity(reference, test, channel_axis=2, data_range=1.0, win_size=win)))


def psnr(reference: np.ndarray, test: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB of two displayed images (capped at PSNR_CAP)."""
    same_size(reference, test)
    mse = float(np.mean((reference.astype(np.float64) - test.astype(np.float64)) ** 2))
    if mse <= 0.0:
        return PSNR_CAP
    return float(min(PSNR_CAP, 10.0 * np.log10(1.0 / mse)))


def quantisation(linear: np.ndarray, bits: int = 8) -> np.ndarray:
    """Half a step of a `bits`-bit sRGB code (1/255 for 8 bits, 1/65535 for 16), in linear units, at
    each value in [0, 1]: the most a PNG's rounding moves it."""
    code = srgb_encode(linear)
    half = 0.5 / (2**bits - 1)
    return (srgb_decode(code + half) - srgb_decode(code - half)) / 2


HALF_ROUNDING = 2.0**-11  # half a unit in the last place of a half float, relative to the value (10 mantissa bits)


@dataclass(frozen=True)
class Encoding:
    """How an image holds its values, so it is compared in its own units (see the module's doc).

    format: "render" (our render: linear float32 radiance), "exr" (linear radiance without exposure;
    bits 32: float, 16: half float) or "png" (sRGB(clamp(2^exposure L)); bits 8 or 16 per channel)."""

    format: str
    bits: int = 32

    @property
    def linear(self) -> bool:
        return self.format != "png"

    def describe(self) -> str:
        if self.format == "png":
            return f"sRGB, {self.bits} bits per channel"
        return "linear radiance, " + ("16-bit half float" if self.bits == 16 else "32-bit float")

    def store(self, linear: np.ndarray, exposure: float = 0.0) -> np.ndarray:
        """What a file of this kind holds for this radiance: for a PNG its displayed values rounded to
        its steps, for a half-float EXR the radiance rounded to half floats, else the radiance."""
        if self.format == "png":  # the arithmetic of tracer.rendering.film.to_srgb8, with 2^bits - 1 steps
            top = 2**self.bits - 1
            scaled = np.nan_to_num(linear, nan=0.0, posinf=1.0, neginf=0.0) * (2.0**exposure)
            codes = np.round(srgb_encode(scaled) * float(top))
            return (codes.astype(np.float64) / top).astype(np.float32)
        stored = linear.astype(np.float16 if self.bits == 16 else np.float32).astype(np.float32)
        return np.nan_to_num(stored, nan=0.0, posinf=0.0, neginf=0.0)  # as an EXR is read (past 65504: inf)

    def rounding(self, values: np.ndarray) -> np.ndarray | None:
        """How far storing may move these values (in the units the z test compares: linear radiance,
        or clamp(2^exposure L) for a PNG); None: no rounding to speak of (32-bit floats)."""
        if self.format == "png":
            return quantisation(values, self.bits)
        if self.bits == 16:
            return np.abs(values) * HALF_ROUNDING + 2.0**-25  # + half the smallest half float
        return None


def pixel_test(
    test: np.ndarray,
    ref_mean: np.ndarray,
    ref_var: np.ndarray,
    n_ref: int,
    n_test: int,
    test_var: np.ndarray | None = None,
    alpha: float = 1e-3,
    rounding: np.ndarray | None = None,
) -> tuple[float, np.ndarray, float]:
    """The share of pixels whose difference from the reference mean is too large for the noise of
    the two estimates, the (H, W) map of each pixel's largest |z|, and the critical value it passed.

    All in one unit: linear radiance, or for a PNG clamp(2^exposure L) (the caller scales and clamps
    the reference). `test_var`: the submission's own sample variance (when we rendered it); None:
    assume the reference's (the null hypothesis: both come from the same distribution). `rounding`:
    how far the submission's storage may have moved each value (`Encoding.rounding`), the q above."""
    same_size(ref_mean, test)
    mean = ref_mean.astype(np.float64)
    var_t = (ref_var if test_var is None else test_var).astype(np.float64)
    sigma2 = var_t / max(n_test, 1) + ref_var.astype(np.float64) / max(n_ref, 1) + FLOOR**2
    if rounding is not None:
        sigma2 = sigma2 + np.asarray(rounding, dtype=np.float64) ** 2
    z = np.abs(test.astype(np.float64) - mean) / np.sqrt(sigma2)
    zmax = np.nan_to_num(z, nan=np.inf).max(axis=-1)
    critical = NormalDist().inv_cdf(1.0 - alpha / 6.0)  # two-sided, alpha split over R, G, B
    return float(np.mean(zmax > critical)), zmax.astype(np.float32), critical
