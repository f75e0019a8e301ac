"""Grading (tracer/grading, server/grading/runs.py, POST /api/grade, `python -m tracer grade`).

The example class in scenes/grading/class (written by scenes/grading/make_class.py) has one student
per case; their grades are asserted exactly, test by test:
alice (correct), bob (no area light), carol (not JSON), dave (correct at 1 spp: noisy), erin (meets
every requirement, wrong picture), frank (schema errors), grace (a correct PNG of her own),
heidi (a wrong EXR), ivan (an image of the wrong size). Students' own images in every format (an EXR
of floats or half floats, an 8- or 16-bit PNG; right, wrong, and the noise baseline's own render) are
made here from our renderer with other seeds (`own_images`).
"""

from __future__ import annotations

import base64
import copy
import dataclasses
import io
import json
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import httpx
import numpy as np
import pytest

from tests.support.api import Server, wait_for
from tests.support.grading import ASSIGNMENT, CLASS, EXAMPLE, assignment_dict
from tests.support.scene import ROOT
from tracer.grading import (
    AssignmentError,
    Grader,
    GradingError,
    InlineRenderer,
    Rendered,
    Submission,
    collect,
    load_assignment,
    metrics,
    read_zip,
    write_all,
)
from tracer.grading.batch import group_files, summary
from tracer.grading.checks import run_check
from tracer.grading.spec import Check
from tracer.kernels.compile import compile_scene
from tracer.rendering.progressive import render
from tracer.scene import load_scene

REQUIREMENTS = ["valid scene", "a glass object", "an area light", "three bounces", "a small scene", "a render budget"]
IMAGE_TESTS = ["FLIP against the reference", "SSIM against the reference", "PSNR against the reference",
               "pixels match the reference"]  # fmt: skip
# Per student: status, then the points of each test in order (scenes: REQUIREMENTS + IMAGE_TESTS;
# images: "readable image" + IMAGE_TESTS).
EXPECTED = {
    "alice": ("graded", [1, 2, 1, 1, 1, 1, 2, 1, 1, 2]),
    "bob": ("graded", [1, 2, 0, 1, 1, 1, 0, 0, 0, 0]),  # no area light: the requirement and the picture
    "carol": ("invalid", [0] * 10),
    "dave": ("graded", [1, 2, 1, 1, 1, 1, 2, 1, 1, 2]),  # 1 spp: as noisy as the baseline, so full marks
    "erin": ("graded", [1, 2, 1, 1, 1, 1, 0, 0, 0, 0]),  # requirements met, picture wrong
    "frank": ("invalid", [0] * 10),
    "grace": ("graded", [1, 2, 1, 1, 2]),
    "heidi": ("graded", [1, 0, 0, 0, 0]),
    "ivan": ("invalid", [0, 0, 0, 0, 0]),
}


@pytest.fixture(scope="module")
def graded():
    assignment, base = load_assignment(ASSIGNMENT)
    grader = Grader(assignment, base, InlineRenderer())
    reports = grader.grade(collect(CLASS))
    return {r.student: r for r in reports}


def test_grading_the_example_class_gives_the_exact_grades(graded):
    assert sorted(graded) == sorted(EXPECTED)
    for student, (status, points) in EXPECTED.items():
        r = graded[student]
        names = REQUIREMENTS + IMAGE_TESTS if r.kind == "scene" else ["readable image"] + IMAGE_TESTS
        assert [t.name for t in r.tests] == names, student
        assert [t.score for t in r.tests] == points, (student, [(t.name, t.output) for t in r.tests])
        assert r.status == status, student
        assert r.score == sum(points)
    assert graded["alice"].max_score == 13
    assert graded["grace"].max_score == 7


def test_grading_an_image_is_out_of_its_own_points_and_its_errors_are_the_image_s(graded):
    """A scene can earn 13 points, an image 7 (readable, and the image tests: the requirements are checks of a
    scene): the spec and the class summary say so per kind; an unreadable image's error is the image's in
    results.json, not "(scene)"."""
    assignment, _ = load_assignment(ASSIGNMENT)
    assert assignment.max_scores() == {"scene": 13.0, "image": 7.0}
    assert summary(list(graded.values()))["statistics"]["max_scores"] == {"scene": 13.0, "image": 7.0}
    assert {r.kind: r.max_score for r in graded.values()} == {"scene": 13.0, "image": 7.0}
    ivan = graded["ivan"]  # an image that cannot be read
    assert ivan.kind == "image"
    assert ivan.errors
    assert not ivan.errors[0]["path"]
    assert ivan.gradescope()["output"].splitlines()[1] == f"(image): {ivan.errors[0]['message']}"


def test_grading_messages_say_why(graded):
    carol = graded["carol"]
    assert "invalid JSON at line 1, column 70" in carol.tests[0].output
    frank = graded["frank"]
    paths = {e["path"] for e in frank.errors}
    assert {"objects[1].radus", "objects[3].material"} <= paths
    assert "did you mean 'radius'" in frank.tests[0].output
    bob_light = graded["bob"].tests[2]
    assert bob_light.output.startswith("failed: found 0 lights with type in [quad, disk, sphere]; wanted >= 1")
    ivan = graded["ivan"]
    assert ivan.errors[0]["message"] == "the image is 64x48 pixels; the assignment renders 96x72"
    erin = graded["erin"]
    assert "(the noise baseline) 0.01662" in erin.tests[6].output
    assert erin.metrics["flip"] > erin.metrics["baseline"]["flip"] + 0.02


def test_grading_is_fair_to_noise(graded):
    """dave's 1-spp render is far from the reference by absolute measures, yet as close as a correct
    1-spp render (the baseline); erin's 16-spp render is closer in PSNR than dave's but fails."""
    dave, erin = graded["dave"].metrics, graded["erin"].metrics
    assert dave["psnr"] < erin["psnr"]
    assert dave["ssim"] < erin["ssim"]
    assert dave["spp"] == 1
    assert erin["spp"] == 16
    assert abs(dave["psnr"] - dave["baseline"]["psnr"]) < 2.0
    assert dave["rejected"] <= dave["baseline"]["rejected"] + 0.01


def test_grading_words_a_correct_noisy_render_reads_as_matching_the_baseline(graded):
    """dave's correct 1-spp render has full marks, and each image test says so first, against a correct render
    at the same samples per pixel (the noise baseline), before any number: 11 % of its pixels past the z test
    read as noise, not failure (before: "11.99 % of pixels differ from the reference by more than the noise
    explains", beside a mostly red picture)."""
    dave = graded["dave"]
    for t in dave.tests[6:]:
        lines = t.output.split("\n")
        assert lines[0] == "Matches the reference as closely as a correct render with 1 sample per pixel does."
        assert "a correct render at 1 sample per pixel (the noise baseline)" in lines[1]
    pixels = dave.tests[9].output.split("\n")
    assert pixels[1].startswith("Pixels off by more than noise explains (a z test per pixel, alpha 0.001; fewer is")
    assert "yours 10.58%; a correct render at 1 sample per pixel (the noise baseline) 11.36%" in pixels[1]
    assert "allowed up to 12.36% (the baseline's + 1.00%)" in pixels[1]
    assert pixels[2] == "At 1 sample per pixel even a correct render has this many: they are noise, not mistakes."
    flip, ssim, psnr = (dave.tests[i].output.split("\n")[1] for i in (6, 7, 8))
    assert flip.startswith("FLIP (how different the two pictures look to a viewer; 0 is identical, lower is better)")
    assert ssim.startswith("SSIM (how alike the pictures' edges, textures and contrast are; 1 is identical, higher")
    assert psnr.startswith("PSNR (the pixels' average error on a log scale; higher is better, 100 dB is identical)")
    assert "allowed at most 0.1074 (the baseline's + 0.02)" in flip
    assert "allowed at least 20.27 dB (the baseline's - 2 dB)" in psnr


def test_grading_words_a_wrong_render_says_it_differs_and_where_to_look(graded):
    """erin's wrong picture: each image test starts with the verdict and its reason, gives the numbers, then
    where to look (the pictures, and what in a scene to compare); heidi's wrong image points at her tracer."""
    erin = graded["erin"]
    for t in erin.tests[6:]:
        verdict, numbers, where = t.output.split("\n")
        assert verdict.startswith("Differs from the reference more than noise can explain: ")
        assert "a correct render at 16 samples per pixel (the noise baseline)" in numbers
        assert where.startswith("Where to look: ")
        assert "rejected pixels" in where
        assert "your scene" in where
    assert erin.tests[9].output.startswith(
        "Differs from the reference more than noise can explain: 12.72% of your pixels are off, where a correct "
        "render at 16 samples per pixel has 0.06%.\n"
    )
    assert erin.tests[6].output.startswith("Differs from the reference more than noise can explain: FLIP 0.07711 "
                                           "is above the 0.03662 allowed")  # fmt: skip
    assert "the FLIP error map (bright where the pictures differ most)" in erin.tests[6].output
    heidi = graded["heidi"].tests[4].output
    assert heidi.startswith("Differs from the reference")
    assert "what your ray tracer computes there" in heidi


RED = (255, 40, 40)


def red_share(pixels: np.ndarray) -> float:
    return float(np.all(pixels == RED, axis=-1).mean())


def test_grading_rejected_picture_marks_red_only_what_noise_does_not_explain(graded):
    """The rejected pixels picture: dave's correct 1-spp render has 11 % of its pixels past the z test, as many
    as the noise baseline, and none of them red (they are pale yellow, "as a correct render has them"); erin's
    wrong cube and ball are red, nearly all her rejected pixels; the caption says both, with the baseline's share."""
    dave, erin = graded["dave"], graded["erin"]
    assert dave.metrics["rejected"] > 0.1 and red_share(dave.images["rejected"]) == 0.0
    yellow = np.all(dave.images["rejected"] == (235, 215, 120), axis=-1).mean()
    assert yellow == pytest.approx(dave.metrics["rejected"], abs=1e-6)  # the metric is rounded to 6 places
    assert dave.metrics["beyond_noise"] == 0.0
    assert red_share(erin.images["rejected"]) > 0.9 * erin.metrics["rejected"]
    assert erin.metrics["beyond_noise"] == pytest.approx(red_share(erin.images["rejected"]), abs=1e-6)
    caption = dave.metrics["captions"]["rejected"]
    assert "red where they differ beyond noise (0.00% of the image)" in caption
    assert caption.endswith("pale yellow as many as noise makes (a correct render at 1 sample per pixel: 11.36%)")
    assert "rejected_map" not in dave.metrics["baseline"]  # the baseline's map is for the picture, not the report


def test_grading_beyond_noise_against_the_baselines_map_and_without_it():
    """beyond_noise by hand: scattered rejections as many as the baseline's at the same places are not red; a
    dense block is, each of its pixels (and the noise's rejections within half a window of it, no further);
    without the baseline's map, against its share spread evenly."""
    from tracer.grading.imagetests import beyond_noise, pack_map, unpack_map

    rng = np.random.default_rng(3)
    baseline = rng.random((40, 60)) < 0.15
    noise = rng.random((40, 60)) < 0.15
    assert not beyond_noise(noise, baseline, 0.15, 1e-3).any()
    assert not beyond_noise(rng.random((40, 60)) < 0.4, rng.random((40, 60)) < 0.4, 0.4, 1e-3).any()
    wrong = noise.copy()
    wrong[10:20, 20:32] = True
    red = beyond_noise(wrong, baseline, 0.15, 1e-3)
    assert red[10:20, 20:32].all()
    near = np.zeros_like(red)
    near[10 - 6 : 20 + 6, 20 - 6 : 32 + 6] = True  # the block and the noise within half a window (and reach) of it
    assert not red[~near].any()
    assert red[10:20, 20:32].all() == beyond_noise(wrong, None, 0.15, 1e-3)[10:20, 20:32].all()
    assert not beyond_noise(noise & (rng.random((40, 60)) < 0.05), None, 0.15, 1e-3).any()
    assert np.array_equal(unpack_map(pack_map(wrong)), wrong)


def test_grading_is_deterministic(graded):
    assignment, base = load_assignment(ASSIGNMENT)
    again = Grader(assignment, base, InlineRenderer(threads=1)).grade(
        [s for s in collect(CLASS) if s.student in ("alice", "dave", "grace")]
    )
    for r in again:
        first = graded[r.student]
        assert r.to_json() | {"render_seconds": 0} == first.to_json() | {"render_seconds": 0}
        for name, pixels in r.images.items():
            np.testing.assert_array_equal(pixels, first.images[name])


def test_grading_writes_reports_gradescope_and_the_summary(graded, tmp_path):
    table = write_all(tmp_path, list(graded.values()))
    results = json.loads((tmp_path / "erin" / "results.json").read_text())
    assert results["score"] == 7.0
    assert [t["name"] for t in results["tests"]] == REQUIREMENTS + IMAGE_TESTS
    assert all({"name", "score", "max_score", "output"} <= set(t) for t in results["tests"])
    assert sum(t["max_score"] for t in results["tests"]) == 13.0
    for name in ("render", "reference", "error_map", "rejected"):
        assert (tmp_path / "erin" / f"{name}.png").stat().st_size > 0
    assert not (tmp_path / "carol" / "render.png").exists()
    csv = (tmp_path / "summary.csv").read_text().splitlines()
    assert csv[0].startswith("student,kind,status,score,max_score,percent,")
    assert [line.split(",")[:6] for line in csv[1:3]] == [
        ["alice", "scene", "graded", "13.0", "13.0", "100.0"],
        ["bob", "scene", "graded", "6.0", "13.0", "46.15"],
    ]
    stats = table["statistics"]
    assert stats["by_status"] == {"graded": 6, "invalid": 3, "failed": 0}
    # scenes are out of 13 points, images out of 7: the class is summed up in percent, never in points
    shares = {row["student"]: row["percent"] for row in table["students"]}
    assert shares["heidi"] == 14.29
    assert shares["grace"] == 100.0
    assert shares["erin"] == 53.85
    assert stats["mean_percent"] == pytest.approx(sum(shares.values()) / 9, abs=0.01)  # 46.03, not 5.2 points
    assert (stats["min_percent"], stats["max_percent"]) == (0.0, 100.0)
    assert "mean" not in stats
    assert json.loads((tmp_path / "summary.json").read_text()) == table


def test_grading_error_map_shows_where_the_picture_is_wrong(graded):
    """erin's cube and ball are wrong: the FLIP error there is far above the floor's."""
    erin = graded["erin"]
    err = erin.images["error_map"].astype(float).sum(axis=-1)
    red = np.all(erin.images["rejected"] == (255, 40, 40), axis=-1)  # beyond noise
    rejected = red | np.all(erin.images["rejected"] == (235, 215, 120), axis=-1)  # ... or as noise has them
    assert rejected.mean() == pytest.approx(erin.metrics["rejected"], abs=1e-6)  # rounded to 6 digits
    assert err[rejected].mean() > 3 * err[~rejected].mean()


# ------------------------------------------------------------------ students' own images: EXR and PNG
#
# An independent ray tracer's image of the reference scene is stood in for by ours with other seeds.
# An EXR holds linear radiance (compared with the reference mean as is), a PNG sRGB(clamp(2^e L)) in 8
# or 16 bits (compared in those units, its rounding in the noise). Each is graded against a noise
# baseline stored the same way, so a correct image scores like the baseline whatever its format.

OWN_SEED = 777  # "the student's" seed: not the reference's (1000003), the baseline's (1000004) or grace's


def render_linear(scene: dict) -> np.ndarray:
    from tracer.kernels.compile import compile_scene
    from tracer.rendering.progressive import render

    return render(compile_scene(load_scene(scene)[0])).image


def exr_bytes(image: np.ndarray, half: bool = False) -> bytes:
    import OpenEXR

    pixels = np.ascontiguousarray(image, dtype=np.float16 if half else np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "image.exr"
        with OpenEXR.File(header, {"RGB": pixels}) as f:
            f.write(str(path))
        return path.read_bytes()


def png16_bytes(codes: np.ndarray) -> bytes:
    """(H, W, 3) or (H, W) 16-bit codes as a PNG written without pypng (zlib and the PNG chunks, each row
    with the Paeth filter, as libpng often chooses), so the reader is checked against an independent writer."""
    import struct
    import zlib

    grey = codes.ndim == 2
    c = codes.reshape(codes.shape[0], codes.shape[1], -1)
    h, w, planes = c.shape
    raw = np.frombuffer(c.astype(">u2").tobytes(), np.uint8).reshape(h, w * planes * 2).astype(np.int32)
    bpp, rows, up = planes * 2, [], np.zeros(w * planes * 2, np.int32)
    for row in raw:
        left = np.concatenate([np.zeros(bpp, np.int32), row[:-bpp]])
        up_left = np.concatenate([np.zeros(bpp, np.int32), up[:-bpp]])
        p = left + up - up_left
        pa, pb, pc = np.abs(p - left), np.abs(p - up), np.abs(p - up_left)
        pred = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, up, up_left))
        rows.append(b"\x04" + ((row - pred) % 256).astype(np.uint8).tobytes())
        up = row

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", w, h, 16, 0 if grey else 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(b"".join(rows)))
        + chunk(b"IEND", b"")
    )


def srgb16(image: np.ndarray) -> np.ndarray:
    """Linear radiance -> 16-bit sRGB codes (exposure 0), the arithmetic of tracer.rendering.film.to_srgb8."""
    from tracer.rendering.film import srgb_encode

    return np.round(srgb_encode(np.nan_to_num(image, nan=0.0, posinf=1.0, neginf=0.0)) * 65535.0).astype(np.uint16)


@pytest.fixture(scope="module")
def own_images():
    """Students' own images of the reference scene: right (another seed, 16 spp as image.spp says) and
    wrong (erin's changes: a grey cube, a blue ball), and the noise baseline's own render, each stored as
    the format says. All graded at once, against one reference."""
    from tracer.rendering.film import png_bytes

    reference = json.loads((EXAMPLE / "reference.json").read_text())
    right = copy.deepcopy(reference)
    right["render"]["seed"] = OWN_SEED
    wrong = copy.deepcopy(right)
    wrong["materials"]["mirror"] = {"kd": 0.5}
    wrong["materials"]["red"] = {"kd": [0.1, 0.2, 0.8]}
    spec, base = load_assignment(ASSIGNMENT)
    baseline = copy.deepcopy(reference)  # what the grader renders as the baseline of a 16-spp image
    baseline["render"]["seed"] = spec.reference.seed + 1
    assert (baseline["sampler"], spec.image.spp) == ({"type": "jittered", "spp": 16}, 16)
    images = {"right": render_linear(right), "wrong": render_linear(wrong), "baseline": render_linear(baseline)}
    files = {
        "right_exr": (exr_bytes(images["right"]), "exr"),
        "right_half_exr": (exr_bytes(images["right"], half=True), "exr"),
        "right_png16": (png16_bytes(srgb16(images["right"])), "png"),
        "wrong_png8": (png_bytes(images["wrong"]), "png"),
        "wrong_png16": (png16_bytes(srgb16(images["wrong"])), "png"),
        "wrong_exr": (exr_bytes(images["wrong"]), "exr"),
        "baseline_exr": (exr_bytes(images["baseline"]), "exr"),
        "baseline_half_exr": (exr_bytes(images["baseline"], half=True), "exr"),
        "baseline_png8": (png_bytes(images["baseline"]), "png"),
        "baseline_png16": (png16_bytes(srgb16(images["baseline"])), "png"),
    }
    reports = Grader(spec, base, InlineRenderer()).grade([Submission(k, d, kind) for k, (d, kind) in files.items()])
    return {r.student: r for r in reports}, images, files


@pytest.mark.parametrize(
    "student, points, encoding",
    [
        ("right_exr", [1, 2, 1, 1, 2], "linear radiance, 32-bit float"),
        ("right_half_exr", [1, 2, 1, 1, 2], "linear radiance, 16-bit half float"),
        ("right_png16", [1, 2, 1, 1, 2], "sRGB, 16 bits per channel"),
        ("wrong_png8", [1, 0, 0, 0, 0], "sRGB, 8 bits per channel"),
        ("wrong_png16", [1, 0, 0, 0, 0], "sRGB, 16 bits per channel"),
        ("wrong_exr", [1, 0, 0, 0, 0], "linear radiance, 32-bit float"),
    ],
)
def test_own_images_are_graded_in_the_units_they_hold(own_images, student, points, encoding):
    """A correct 16-spp image scores 7/7 whether it is an EXR (linear radiance: it scored 1/7 when it
    was read as displayed values) or a PNG; a wrong one fails the four image tests in every format."""
    report = own_images[0][student]
    assert [t.score for t in report.tests] == points, [(t.name, t.output) for t in report.tests]
    assert report.metrics["encoding"] == encoding
    assert report.tests[0].output == f"a 96x72 {student.rsplit('_', 1)[1][:3].upper()} image ({encoding})"


@pytest.mark.parametrize("fmt", ["exr", "half_exr", "png8", "png16"])
def test_own_images_the_baselines_own_render_scores_exactly_the_baseline(own_images, fmt):
    """Like with like: the noise baseline is stored as the submission was (a PNG's 8- or 16-bit steps,
    a half float's rounding), so a file of the baseline's own render measures exactly as the baseline.
    Tolerance: a relative 1e-6 (the same arithmetic on the same values; the file's round trip is exact)."""
    m = own_images[0][f"baseline_{fmt}"].metrics
    for key in ("flip", "ssim", "psnr", "rejected"):
        assert m[key] == pytest.approx(m["baseline"][key], rel=1e-6, abs=1e-9), (key, m)


def test_own_images_an_exr_is_compared_as_linear_radiance(own_images):
    """The correct EXR is as close to the reference as the float baseline, and its z test has no 8-bit
    term: radiance 0.001 too bright (less than half an 8-bit step at these values) is rejected where
    the reference has no noise (the sky: a quarter of the picture), while as a PNG the steps hide it."""
    from tracer.rendering.film import png_bytes

    reports, images, _ = own_images
    exr = reports["right_exr"].metrics
    assert exr["psnr"] == pytest.approx(exr["baseline"]["psnr"], abs=1.0)  # 40.5 dB against 40.4
    assert exr["rejected"] <= exr["baseline"]["rejected"] + 0.002  # 0 of 6912 pixels against 1
    spec, base = load_assignment(ASSIGNMENT)
    brighter = images["right"] + 0.001
    shifted = [Submission("exr", exr_bytes(brighter), "exr"), Submission("png", png_bytes(brighter), "png")]
    exr, png = Grader(spec, base, InlineRenderer()).grade(shifted)
    assert exr.metrics["rejected"] > 0.2 and exr.tests[-1].score == 0, exr.metrics  # 25.7%
    assert png.metrics["rejected"] < 0.005 and png.tests[-1].score == 2, png.metrics  # 0.06%


def test_own_images_16_bit_pngs_keep_their_16_bits():
    """Pillow reads a 48-bit PNG as 24-bit: the grader decodes 16 bits (RGB and grey), and says the depth."""
    from tracer.grading import read_image

    codes = np.arange(4 * 6 * 3, dtype=np.uint16).reshape(4, 6, 3) * 911 + 3
    np.testing.assert_allclose(read_image(png16_bytes(codes), "png"), codes / 65535.0, rtol=0, atol=1e-7)
    grey = read_image(png16_bytes(codes[..., 0]), "png")
    np.testing.assert_allclose(grey, np.repeat(codes[..., :1], 3, axis=-1) / 65535.0, rtol=0, atol=1e-7)
    from tracer.grading.submission import decode_image

    assert decode_image(png16_bytes(codes), "png")[1] == metrics.Encoding("png", 16)
    assert decode_image(png16_bytes(codes[..., 0]), "png")[1] == metrics.Encoding("png", 16)
    with pytest.raises(GradingError, match="cannot read the PNG image"):
        decode_image(png16_bytes(codes)[:60], "png")  # cut short in its pixels


def test_own_images_quantisation_steps_follow_the_bit_depth():
    """Half a step of the PNG's code, in linear units: 1/255 for 8 bits, 1/65535 for 16; an EXR of 32-bit
    floats adds none, one of half floats 2^-11 of the value."""
    x = np.array([0.001, 0.2, 0.5, 0.9])
    q8, q16 = metrics.quantisation(x, 8), metrics.quantisation(x, 16)
    np.testing.assert_allclose(q16 / q8, 255 / 65535, rtol=2e-3)  # the sRGB curve is smooth at these steps
    slope = 2.4 / 1.055 * 0.5 ** (1.4 / 2.4)  # d linear / d code of the sRGB curve at linear 0.5
    assert q8[2] == pytest.approx(0.5 / 255 * slope, rel=1e-3)
    assert metrics.Encoding("exr", 32).rounding(x) is None
    np.testing.assert_allclose(metrics.Encoding("exr", 16).rounding(x), x * 2.0**-11, atol=1e-7)
    stored = metrics.Encoding("png", 16).store(np.array([[[0.5, 0.5, 0.5]]]))
    assert stored[0, 0, 0] * 65535 == pytest.approx(round(float(metrics.display(np.array([0.5]))[0]) * 65535))


def test_own_images_exr_channels_are_said_so(tmp_path):
    import OpenEXR

    from tracer.grading.submission import decode_image

    path = str(tmp_path / "image.exr")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"Z": np.ones((4, 4), np.float32)}) as f:
        f.write(path)
    with pytest.raises(GradingError, match="the EXR image has no colour: R, G and B .or Y. channels wanted; it has Z"):
        decode_image(open(path, "rb").read(), "exr")
    rgba = np.concatenate([np.full((4, 4, 3), 0.25, np.float16), np.ones((4, 4, 1), np.float16)], axis=-1)
    with OpenEXR.File(header, {"RGBA": rgba}) as f:
        f.write(path)
    image, encoding = decode_image(open(path, "rb").read(), "exr")
    assert image.shape == (4, 4, 3) and np.all(image == 0.25) and encoding == metrics.Encoding("exr", 16)


# ------------------------------------------------------------------------------------ the spec


@pytest.mark.parametrize(
    "change, path, words",
    [
        (lambda a: a["requirements"][0].update(check="glas"), "requirements[0].check",
         "unknown preset 'glas' (the presets: transmissive_material, reflective_material, glossy_material, "),
        (lambda a: a["requirements"][1].update(check="area_ligth"), "requirements[1].check",
         "unknown preset 'area_ligth'; did you mean 'area_light'? (the presets: transmissive_material, "),
        (lambda a: a["requirements"][1].update(points=-1), "requirements[1].points", "must be >= 0"),
        (lambda a: a["requirements"][2]["check"].update(at_lest=3), "requirements[2].check.at_lest",
         "unknown field 'at_lest'; did you mean 'at_least'?"),
        (lambda a: a["requirements"][2]["check"].update(count="materialz"), "requirements[2].check.count",
         "expected one of: materials, lights, objects, primitives; got \"materialz\"; did you mean 'materials'?"),
        (lambda a: a["requirements"][2]["check"].pop("at_least"), "requirements[2].check", "at least one comparison"),
        (lambda a: a["requirements"][3]["check"].update(where={"kt": {"bigger": 0}}), "requirements[3].check",
         "unknown comparison 'bigger'"),
        (lambda a: a.pop("name"), "name", "required"),
        (lambda a: a["reference"].update(spp=0), "reference.spp", "must be >= 1"),
        (lambda a: a["render"].update(integrator="pathh"), "render.integrator", "did you mean 'path'?"),
        (lambda a: a["reference"].update(scene=5), "reference.scene", "expected a JSON object {...}, got 5"),
        (lambda a: a.update(colour=1), "colour", "unknown field"),
    ],
)  # fmt: skip
def test_assignment_errors_name_the_field(change, path, words):
    a = assignment_dict()
    change(a)
    with pytest.raises(AssignmentError) as e:
        load_assignment(a)
    assert any(x["path"] == path and words in x["message"] for x in e.value.errors), e.value.errors


MANUAL = [{"name": "creativity", "points": 3, "instructions": "More than the starter?",
           "rubric": [{"name": "new objects", "points": 2, "description": "two or more"},
                      {"name": "a story", "points": 1.5}, {"name": "copied", "points": -3}]},
          {"name": "lighting", "points": 2, "rubric": [{"name": "area light", "points": 2}]}]  # fmt: skip


def test_assignment_manual_items_are_optional_and_score_their_chosen_levels_clamped():
    assert load_assignment(assignment_dict())[0].manual == []
    a = assignment_dict()
    a["manual"] = MANUAL
    spec, _ = load_assignment(a)
    creativity = spec.manual_item("creativity")
    assert spec.manual_points() == 5 and spec.max_score() == load_assignment(assignment_dict())[0].max_score()
    assert creativity.score(["new objects"]) == 2 and creativity.score(["new objects", "a story"]) == 3  # clamped
    assert creativity.score(["a story", "copied"]) == 0 and creativity.score(["gone"]) == 0  # never below 0
    assert creativity.level("a story").points == 1.5 and spec.manual_item("nope") is None


@pytest.mark.parametrize(
    "change, path, words",
    [
        (lambda m: m.append(dict(m[1])), "manual[2].name", "a second item named 'lighting'"),
        (lambda m: m[0]["rubric"].append({"name": "a story", "points": 1}), "manual[0].rubric[3].name",
         "a second level named 'a story'"),
        (lambda m: m[1]["rubric"][0].update(points=2.5), "manual[1].rubric[0].points",
         "expected points within -2..2 (the item's); got 2.5"),
        (lambda m: m[0]["rubric"][2].update(points=-4), "manual[0].rubric[2].points", "within -3..3"),
        (lambda m: m[0].update(points=0), "manual[0].points", "must be > 0"),
        (lambda m: m[1].update(rubric=[]), "manual[1].rubric", "at least 1"),
        (lambda m: m[1]["rubric"].extend({"name": str(i), "points": 0} for i in range(9)), "manual[1].rubric",
         "at most 9"),
        (lambda m: m[0].update(grader="x"), "manual[0].grader", "unknown field"),
    ],
)  # fmt: skip
def test_assignment_manual_errors_name_the_field(change, path, words):
    a = assignment_dict()
    a["manual"] = json.loads(json.dumps(MANUAL))
    change(a["manual"])
    with pytest.raises(AssignmentError) as e:
        load_assignment(a)
    assert any(x["path"] == path and words in x["message"] for x in e.value.errors), e.value.errors


def test_assignment_reference_must_be_a_valid_scene():
    a = assignment_dict()
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    a["reference"]["scene"]["objects"][1]["radius"] = -1
    spec, _ = load_assignment(a)
    with pytest.raises(AssignmentError) as e:
        Grader(spec, None)
    assert e.value.errors[0]["path"] == "reference.scene.objects[1].radius"
    a["reference"]["scene"] = "reference.json"
    spec, _ = load_assignment(a)
    with pytest.raises(AssignmentError, match="give the scene inline"):
        Grader(spec, None)


def test_checks_count_compare_and_presets():
    scene, _ = load_scene(json.loads((EXAMPLE / "reference.json").read_text()))

    def check(**kw):
        return run_check(scene, Check(**kw))[0]

    assert check(count="materials", where={"kt": {"greater_than": 0}, "ior": {"greater_than": 1}}, at_least=1)
    assert not check(count="materials", where={"kt": {"greater_than": 0}, "ior": {"greater_than": 1.6}}, at_least=1)
    assert check(count="materials", where={"kd": {"greater_than": 0.7}}, equals=2)  # floor 0.8, red's max 0.75
    assert check(count="primitives", equals=1 + 1 + 12 + 1)  # a plane, two spheres, a box of 12 triangles
    assert check(count="lights", where={"type": "quad"}, equals=1)
    assert check(count="objects", where={"velocity": {"present": True}}, equals=0)
    assert check(value="render.max_depth", at_least=3, at_most=4)
    assert not check(value="camera.lens_radius", greater_than=0)
    assert check(value="materials.glass.ior", one_of=[1.5, 1.33])
    found = run_check(scene, Check(value="render.no_such_thing", equals=1))
    assert found == (False, "render.no_such_thing: no such field in the scene")


# ----------------------------------------------------------------------------------- metrics


def test_metrics_flip_never_exits_the_process():
    a = np.full((8, 8, 3), 0.5, np.float32)
    assert metrics.flip(a, a)[0] == 0.0
    with pytest.raises(GradingError, match="pixels per degree must be positive"):
        metrics.flip(a, a, ppd=-1.0)  # flip_evaluator calls sys.exit(1) here
    with pytest.raises(GradingError, match="the image is 4x8 pixels; the reference is 8x8"):
        metrics.flip(a, a[:, :4])


def test_metrics_pixel_test_rejects_about_alpha_for_pure_noise():
    rng = np.random.default_rng(5)
    truth = rng.uniform(0.1, 0.9, (200, 200, 3))
    var = np.full_like(truth, 0.04)
    ref = truth + rng.normal(0, np.sqrt(0.04 / 256), truth.shape)
    noisy = truth + rng.normal(0, np.sqrt(0.04 / 4), truth.shape)
    rejected, _, critical = metrics.pixel_test(noisy, ref, var, 256, 4, alpha=1e-3)
    assert critical == pytest.approx(3.588, abs=1e-3)  # 1e-3 split over two tails and three channels
    assert rejected < 3e-3  # expected 1e-3 of 40 000 pixels; 3e-3 is 6 sigma of a binomial away
    wrong = noisy.copy()
    wrong[:50] += 0.5  # a quarter of the picture 5 standard deviations too bright
    rejected, z, _ = metrics.pixel_test(wrong, ref, var, 256, 4, alpha=1e-3)
    assert rejected > 0.24 and z[:50].mean() > 3 * z[50:].mean()


def test_metrics_ssim_psnr_bounds():
    a = np.random.default_rng(1).uniform(0, 1, (16, 16, 3)).astype(np.float32)
    assert metrics.ssim(a, a) == pytest.approx(1.0)
    assert metrics.psnr(a, a) == metrics.PSNR_CAP
    assert metrics.psnr(a, np.clip(a + 0.1, 0, 1)) < 21
    with pytest.raises(GradingError, match="too small"):
        metrics.ssim(a[:2, :2], a[:2, :2])


# ------------------------------------------------------------------------------ submissions


def test_batch_collects_folders_and_zips(tmp_path):
    subs = {s.student: s for s in collect(CLASS)}
    assert subs["frank"].kind == "scene"
    assert subs["frank"].filename == "frank/scene.json"
    assert subs["heidi"].kind == "exr"
    assert subs["grace"].kind == "png"
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("hw4/zed.json", "{}")
        z.writestr("hw4/yan/picture.png", b"not really")
        z.writestr("hw4/yan/scene.json", "{}")  # a folder with a scene and an image: the scene
        z.writestr("hw4/.hidden.json", "{}")
        z.writestr("hw4/../escape.json", "{}")
        z.writestr("hw4/notes.txt", "ignored")
    (tmp_path / "class.zip").write_bytes(buf.getvalue())
    subs = collect(tmp_path / "class.zip")
    assert [(s.student, s.kind, s.filename) for s in subs] == [("yan", "scene", "yan/scene.json"),
                                                               ("zed", "scene", "zed.json")]  # fmt: skip
    with pytest.raises(GradingError, match="not a zip file"):
        read_zip(b"PK nonsense")


def test_student_names_keep_unicode_letters(tmp_path):
    """A student is named after their file: letters of any script stay (NFC, as macOS's NFD names come
    out the same), other characters become '_'; from a folder, a zip (UTF-8 names without the zip's
    UTF-8 flag, as macOS and Linux write them) and the CLI alike."""
    import unicodedata

    from tracer.grading import student_for_file, student_name

    assert student_name("Zoë O'Brien") == "Zoë_O_Brien"
    assert student_name(unicodedata.normalize("NFD", "Zoë O'Brien")) == "Zoë_O_Brien"
    assert student_name("प्रिया शर्मा") == "प्रिया_शर्मा"  # vowel signs are marks (M*), not letters
    assert [student_name(x) for x in ("王小明", "Ελένη", "../etc/passwd", "..hidden", "😀", "")] == [
        "王小明", "Ελένη", "etc_passwd", "hidden", "student", "student"]  # fmt: skip
    assert len(student_name("𝐀" * 100).encode()) <= 240  # a folder name: at most 255 bytes
    assert student_for_file("hw4/Zoë O'Brien.json") == "Zoë_O_Brien"
    (tmp_path / "Zoë O'Brien.json").write_text("{}")
    assert [s.student for s in collect(tmp_path)] == ["Zoë_O_Brien"]
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("hw4/Zoë O'Brien.json", "{}")  # Python sets the UTF-8 flag
        z.writestr("hw4/JosXX/scene.json", "{}")  # ASCII: no flag; its bytes become UTF-8 "José" below
    data = buf.getvalue().replace(b"hw4/JosXX/", "hw4/José/".encode())  # as macOS's and Linux's zip write it
    assert zipfile.ZipFile(io.BytesIO(data)).namelist()[1] == "hw4/Jos├⌐/scene.json"  # read as code page 437
    entries = read_zip(data)
    assert sorted(entries) == ["hw4/José/scene.json", "hw4/Zoë O'Brien.json"]
    assert [s.student for s in group_files(entries)] == ["José", "Zoë_O_Brien"]


# ---------------------------------------------------------------------------------------- CLI


def run_cli(*args, cwd=ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tracer", "grade", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600)  # fmt: skip


def test_cli_grades_one_scene(tmp_path):
    p = run_cli(ASSIGNMENT, CLASS / "bob.json", "-o", tmp_path)
    assert p.returncode == 0, p.stderr
    assert p.stdout.splitlines()[0] == "bob: 6 / 13 = 46.2% (graded)"
    assert "FAIL an area light (0/1): failed: found 0 lights" in p.stdout
    assert json.loads((tmp_path / "bob" / "results.json").read_text())["score"] == 6.0


def test_cli_writes_beside_the_submission_without_an_output_folder(tmp_path):
    """Without -o the reports go beside what is graded, named after it (bob.json -> bob-grades/), not into
    the directory the command runs in (a checkout's); git ignores both that and a ./grades/ folder."""
    (tmp_path / "hw").mkdir()
    (tmp_path / "hw" / "bob.json").write_bytes((CLASS / "bob.json").read_bytes())
    p = run_cli(ASSIGNMENT, tmp_path / "hw" / "bob.json")
    assert p.returncode == 0, p.stderr
    assert p.stdout.splitlines()[-1] == f"report and pictures in {tmp_path / 'hw' / 'bob-grades' / 'bob'}/"
    assert json.loads((tmp_path / "hw" / "bob-grades" / "bob" / "results.json").read_text())["score"] == 6.0
    ignored = subprocess.run(["git", "check-ignore", "grades/x", "scenes/grading/class-grades/x"], cwd=ROOT,
                             capture_output=True, text=True)  # fmt: skip
    assert ignored.stdout.split() == ["grades/x", "scenes/grading/class-grades/x"], ignored


def test_cli_grades_a_class_through_the_job_queue(tmp_path):
    """A zip of three students, rendered by worker processes of the CLI's own (tracer.grading.local)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name in ("alice.json", "carol.json", "grace.png"):
            z.write(CLASS / name, f"hw4/{name}")
    (tmp_path / "hw4.zip").write_bytes(buf.getvalue())
    p = run_cli(ASSIGNMENT, tmp_path / "hw4.zip", "-o", tmp_path / "out", "--workers", "1")
    assert p.returncode == 0, p.stderr
    assert "alice: 13 / 13 = 100% (graded)\ncarol: 0 / 13 = 0% (invalid)\ngrace: 7 / 7 = 100% (graded)" in p.stdout
    assert "3 students, mean 66.7% of the points; summary in" in p.stdout
    assert "renders done: 3/3" in p.stderr  # the reference, one baseline and alice's scene
    rows = (tmp_path / "out" / "summary.csv").read_text().splitlines()
    assert len(rows) == 4
    # the workers' log lines go to a file, which the CLI names; the terminal has the progress alone
    log = tmp_path / "out" / ".queue" / "workers.log"
    assert f"the render workers log to {log}" in p.stderr
    assert [line for line in p.stderr.splitlines() if not line.startswith(("renders done", "the render workers"))] == []
    assert "INFO tracer.grading.local" in log.read_text()
    assert "render worker" in log.read_text()


def test_cli_reports_a_bad_assignment(tmp_path):
    a = assignment_dict()
    a["requirements"][0]["check"] = "glas"
    (tmp_path / "a.json").write_text(json.dumps(a))
    p = run_cli(tmp_path / "a.json", CLASS / "alice.json", "-o", tmp_path)
    assert p.returncode == 1
    assert "error: assignment: requirements[0].check: unknown preset 'glas'" in p.stderr


# ---------------------------------------------------------------------------------------- API


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with Server(tmp_path_factory.mktemp("grade-data"), workers=2) as s:
        yield s


def inline_assignment(**limits) -> dict:
    a = assignment_dict()
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    a["limits"].update(limits)
    return a


def test_api_grades_a_class_with_a_time_limit_per_student(server):
    """A slow submission is stopped at the assignment's limit and fails alone; the others are graded."""
    slow = json.loads((CLASS / "alice.json").read_text())
    slow["sampler"] = {"type": "jittered", "spp": 64}  # the assignment's max_spp
    slow["render"].update(light_samples=16, max_depth=16, min_weight=0)  # its max_light_samples
    # ~40 s of rendering against a limit of 6 s: the others' renders (under a second each on a quiet machine) stay
    # under it on a loaded one too (with 2 s, a machine at load 20 once stopped alice's)
    slow["lights"] = slow["lights"] * 16
    body = {
        "assignment": inline_assignment(max_seconds=6),
        "submissions": [
            {"student": "alice", "scene": json.loads((CLASS / "alice.json").read_text())},
            {"student": "carol", "scene": (CLASS / "carol.json").read_text()},
            {"student": "grace", "image": base64.b64encode((CLASS / "grace.png").read_bytes()).decode()},
            {"student": "sam", "scene": slow},
        ],
    }
    r = httpx.post(f"{server.url}/api/grade", json=body, timeout=30)
    assert r.status_code == 202, r.text
    run = r.json()
    assert r.headers["location"] == run["url"]
    assert run["status"] == "running"
    state = wait_for(lambda: (s := httpx.get(server.url + run["url"]).json())["status"] != "running" and s,
                     timeout=300, what="the grading run", interval=0.5)  # fmt: skip
    assert state["status"] == "done", state
    scores = {x["student"]: (x["score"], x["status"]) for x in state["reports"]}
    assert scores["alice"] == (13.0, "graded")
    assert scores["carol"] == (0.0, "invalid")
    assert scores["grace"] == (7.0, "graded")
    sam = next(x for x in state["reports"] if x["student"] == "sam")
    assert scores["sam"] == (7.0, "failed")  # its requirements pass, its picture was never finished
    limit = "over the time limit of 6 s per render (set by the assignment's limits.max_seconds)"
    assert limit in sam["tests"][6]["output"]
    assert "TRACER_MAX_JOB_SECONDS" not in sam["tests"][6]["output"]
    csv = httpx.get(f"{server.url}{run['url']}/summary.csv").text
    assert csv.splitlines()[1].startswith("alice,scene,graded,13.0,13.0")
    png = httpx.get(f"{server.url}{run['url']}/students/alice/error_map.png")
    assert png.status_code == 200
    assert png.content[:4] == b"\x89PNG"
    results = httpx.get(f"{server.url}{run['url']}/students/grace/results.json").json()
    assert results["score"] == 7.0
    assert httpx.get(f"{server.url}{run['url']}/students/alice/secret.txt").status_code == 404
    assert httpx.get(f"{server.url}{run['url']}/students/..%2Fx/report.json").status_code == 404


def test_api_grade_rejects_bad_requests(server):
    a = inline_assignment()
    a["requirements"][0]["check"] = "glas"
    r = httpx.post(f"{server.url}/api/grade", json={"assignment": a, "scene": {}})
    assert r.status_code == 422
    assert r.json()["errors"][0]["path"] == "assignment.requirements[0].check"
    a = assignment_dict()  # the reference as a file name: only the CLI can read it
    r = httpx.post(f"{server.url}/api/grade", json={"assignment": a, "scene": {}})
    assert r.status_code == 422
    assert "give the scene inline" in r.json()["errors"][0]["message"]
    r = httpx.post(f"{server.url}/api/grade", json={"assignment": inline_assignment()})
    assert r.status_code == 422
    assert "exactly one of" in r.text
    r = httpx.post(f"{server.url}/api/grade", json={"assignment": inline_assignment(), "zip": "***"})
    assert r.status_code == 422
    assert r.json()["errors"][0] == {"path": "zip", "message": "expected base64 data"}
    assert httpx.get(f"{server.url}/api/grade/{'0' * 32}").status_code == 404
    schema = httpx.get(f"{server.url}/api/grade/schema").json()
    assert {"name", "requirements", "reference", "limits"} <= set(schema["properties"])
    assert "Check" in schema["$defs"]
    assert "at_least" in schema["$defs"]["Check"]["properties"]


def test_api_grade_example_is_the_example_class(server):
    ex = httpx.get(f"{server.url}/api/grade/example").json()
    assert [s["student"] for s in ex["submissions"]] == sorted(EXPECTED)
    assert isinstance(ex["assignment"]["reference"]["scene"], dict)
    grace = next(s for s in ex["submissions"] if s["student"] == "grace")
    assert base64.b64decode(grace["image"]) == (CLASS / "grace.png").read_bytes()


def test_queue_and_inline_give_the_same_grade(server, graded):
    """The same submission through the service's job queue and in process: the same report."""
    body = {"assignment": inline_assignment(), "scene": (CLASS / "erin.json").read_text()}
    run = httpx.post(f"{server.url}/api/grade", json=body).json()
    state = wait_for(lambda: (s := httpx.get(server.url + run["url"]).json())["status"] != "running" and s,
                     timeout=300, what="the grading run", interval=0.5)  # fmt: skip
    report = state["reports"][0]
    mine = graded["erin"].to_json()
    for key in ("score", "status", "tests", "metrics"):
        assert report[key] == json.loads(json.dumps(mine[key])), key


def test_api_names_students_as_the_grader_does(server):
    """The page asks the server to name picked files (it keeps no copy of the rule)."""
    r = httpx.post(f"{server.url}/api/grade/students", json={"files": ["Zoë O'Brien.json", "bob.png", "x y.exr"]})
    assert r.status_code == 200
    assert r.json() == {"students": ["Zoë_O_Brien", "bob", "x_y"]}
    assert httpx.post(f"{server.url}/api/grade/students", json={"names": []}).status_code == 422


def test_grading_limits_are_the_tables_within_the_services():
    """An assignment's limits tighten some of the table's (tracer/limits.py); the others are the defaults,
    and a render through the service takes the tighter of the assignment's and the service's."""
    from server.core.settings import Settings
    from server.grading.renders import capped
    from tracer.limits import NAMES, Limits

    spec, _ = load_assignment(inline_assignment(max_spp=64))
    fields = [name for name in type(spec.limits).model_fields if name.startswith("max_") and name != "max_seconds"]
    assert set(fields) <= set(NAMES)
    limits = spec.limits.scene_limits()
    assert limits == Limits(**{name: getattr(spec.limits, name) for name in fields}) and limits.max_spp == 64
    job = Grader(spec, None)._job("alice", json.loads((CLASS / "alice.json").read_text()), 0)
    got, _, _ = capped(job, Settings(max_spp=16, max_width=4096, max_patches=5))
    assert got == limits.tighter(Limits(max_spp=16, max_width=4096, max_patches=5))
    assert (got.max_spp, got.max_width, got.max_patches) == (16, spec.limits.max_width, 5)


@pytest.mark.parametrize(
    "service_seconds, priority, killed, expected",
    [
        (600, 0, False, "over the time limit of 2 s per render (set by the assignment's limits.max_seconds)"),
        (1, 0, False, "over the time limit of 1 s per render (set by the server's max_job_seconds, "
                      "TRACER_MAX_JOB_SECONDS)"),
        (600, 10, True, "over the time limit of 20 s per render (set by 10 x the assignment's limits.max_seconds, "
                        "for the reference renders); its worker was killed"),
    ],
)  # fmt: skip
def test_time_limit_messages_cite_what_set_the_limit(service_seconds, priority, killed, expected):
    """The worker only knows its job's seconds, and names TRACER_MAX_JOB_SECONDS; the grader knows
    whether the assignment's limit, the service's, or the reference's (ten times the assignment's) set them."""
    from server.core.settings import Settings
    from server.grading.renders import capped, job_outcome

    spec, _ = load_assignment(inline_assignment(max_seconds=2))
    grader = Grader(spec, None)
    scene = json.loads((CLASS / "alice.json").read_text())
    job = grader._job("reference" if priority else "alice", scene, priority)
    worker_said = "stopped: over the time limit of 9 s per job (TRACER_MAX_JOB_SECONDS)" + ("; worker killed" * killed)
    _, seconds, source = capped(job, Settings(max_job_seconds=service_seconds))
    error, _, _ = job_outcome({"id": "0", "status": "failed", "error": worker_said}, seconds, source)
    assert error == "stopped: " + expected
    if service_seconds == 600 and not killed:  # rendered here: the same words
        inline = InlineRenderer().one(dataclasses.replace(job, max_seconds=1e-9))
        assert inline.error == "stopped: " + expected.replace(" 2 s ", " 1e-09 s ")


def test_grading_copes_with_a_submission_made_invalid_by_the_settings():
    """The assignment fixes a grid sampler; a student's 5 spp is no perfect square: told, not crashed."""
    a = copy.deepcopy(inline_assignment())
    a["render"]["sampler"] = "grid"
    spec, _ = load_assignment(a)
    scene = json.loads((CLASS / "alice.json").read_text())
    scene["sampler"] = {"type": "random", "spp": 5}
    report = Grader(spec, None).grade_one(Submission("x", json.dumps(scene).encode()))
    assert report.status == "failed"
    assert "must be a perfect square" in report.tests[-1].output
    assert report.score == 7.0


def test_grading_validity_resolves_asset_files():
    """A missing mesh file costs the validity points, with the asset's message; the scene is never
    rendered (no more "valid scene" then "not compared: invalid scene")."""
    spec, _ = load_assignment(inline_assignment())
    scene = json.loads((CLASS / "alice.json").read_text())
    scene["objects"].append({"type": "mesh", "file": "teapot.obj", "material": {"kd": 0.5}})
    rendered = []

    def renderer(jobs):
        rendered.extend(job.name for job in jobs)
        return [Rendered(error="not rendered in this test") for _ in jobs]

    report = Grader(spec, None, renderer).grade_one(Submission("x", json.dumps(scene).encode()))
    valid = report.tests[0]
    assert (valid.name, valid.score, report.status) == ("valid scene", 0.0, "invalid")
    path = f"objects[{len(scene['objects']) - 1}].file"
    assert f"{path}: asset file 'teapot.obj' not found in the asset folder" in valid.output
    assert report.errors[0]["path"] == path
    assert {t.output for t in report.tests if t.kind == "image"} == {"not compared: the scene is invalid"}
    assert "x" not in rendered


def test_unreadable_images_are_said_so():
    from tracer.grading import read_image

    with pytest.raises(GradingError, match="cannot read the EXR image: it is not an OpenEXR file"):
        read_image(b"hello", "exr")
    with pytest.raises(GradingError, match="cannot read the PNG image"):
        read_image(b"hello", "png")
    grey16 = io.BytesIO()
    from PIL import Image

    Image.fromarray(np.full((4, 6), 65535, np.uint16)).save(grey16, format="PNG")
    image = read_image(grey16.getvalue(), "png")
    assert image.shape == (4, 6, 3) and np.all(image == 1.0)


@pytest.mark.parametrize(
    ("fmt", "told"),
    [("EPS", "a PostScript (EPS) file"), ("GIF", "a GIF image"), ("BMP", "a BMP image"), ("TGA", "not a PNG file")],
)
def test_own_images_of_other_formats_are_refused_before_any_decoder(fmt, told, monkeypatch):
    """A student's .png that is another format Pillow reads (an EPS would go through Ghostscript): refused by
    its first bytes, Pillow never called; an .exr that is not one never reaches OpenEXR either."""
    from PIL import Image

    from tracer.grading.submission import decode_image

    picture = io.BytesIO()
    Image.new("RGB", (4, 2), (255, 128, 0)).save(picture, format=fmt)
    monkeypatch.setattr(Image, "open", lambda *a, **k: pytest.fail("Pillow opened it"))
    with pytest.raises(GradingError) as e:
        decode_image(picture.getvalue(), "png")
    assert str(e.value) == f"cannot read the PNG image: it is {told}; a submitted image is a PNG or an OpenEXR file"
    with pytest.raises(GradingError) as e:
        decode_image(picture.getvalue(), "exr")
    assert str(e.value).startswith("cannot read the EXR image: it is ")


def test_grading_example_reference_shows_its_mirror_cube():
    """The example assignment asks for a mirror cube, and its reference at the assignment's 96x72 shows one (issue
    #42: a plain mirror cube reflected the checkered floor and read as floor, 3 to 4 % off the colour of what it
    hid). The cube's pixels (where the eye ray meets it first: a probe render with it painted green, its albedo)
    are a tenth of the picture, and their mean colour differs from the picture's there without the cube by
    more than 0.1 (sRGB, 0 to 1) in some channel: a gold mirror turned 45 degrees."""
    reference = json.loads((EXAMPLE / "reference.json").read_text())
    assert assignment_dict()["render"] == {"width": 96, "height": 72, "seed": 7}
    reference["sampler"]["spp"] = 16

    def render_of(scene: dict):
        s, _ = load_scene(scene)
        return render(compile_scene(s), threads=2)

    probe = copy.deepcopy(reference)
    probe["materials"]["mirror"] = {"kd": [0, 1, 0]}
    cube = np.abs(render_of(probe).aovs["albedo"] - [0, 1, 0]).max(axis=-1) < 0.05
    assert cube.mean() > 0.05, cube.mean()
    gone = copy.deepcopy(reference)
    gone["objects"] = [o for o in gone["objects"] if o.get("name") != "mirror cube"]
    assert len(gone["objects"]) == len(reference["objects"]) - 1

    def srgb(image: np.ndarray) -> np.ndarray:
        return np.clip(image, 0, 1) ** (1 / 2.2)

    seen, hidden = srgb(render_of(reference).image)[cube], srgb(render_of(gone).image)[cube]
    assert np.abs(seen.mean(axis=0) - hidden.mean(axis=0)).max() > 0.1, (seen.mean(axis=0), hidden.mean(axis=0))
