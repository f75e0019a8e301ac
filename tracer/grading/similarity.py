"""Similarity reports of a class (docs/assignments.md, "5. Similarity reports"): which students' submissions are much
closer to each other than the class's usual, explained fact by fact, for a person to look at. Never a verdict.

**Scenes** are compared as canonical scenes (tracer/grading/canonical.py): sets of `path=value` facts, names and
order forgotten, numbers on a grid, the starter scene's facts taken away, and so are the facts that many of the
class share (held by COMMON_SHARE of the students and at least COMMON_MIN of them: what the task asked for, or
a tutorial's scene, is no evidence between two of them). The distance of two students is 1 - Jaccard of those
own facts (0: the same facts; 1: none in common).

**Candidates, not every pair** (Broder 1997; Indyk and Motwani 1998). Each student's own facts get a MinHash
signature of PERMUTATIONS values; the signature is cut into BANDS bands of ROWS rows, and two students whose
signatures agree on every row of some band are a candidate pair (a bucket per band). Two students of Jaccard J
are one with probability 1 - (1 - J^ROWS)^BANDS: 0.996 at J = 0.5 (where flagging starts), 0.04 at J = 0.1.
Only candidates get the exact distance; the rest of the class is known by the signatures' agreement, an
estimate of J, which is all the usual distance needs.

**Images** (an open-ended task's renders) by a perceptual measure: each picture in grey at THUMB x THUMB (each
pixel the mean of its area, so that a render's noise and a few pixels' edits wash out), the distance the RMS
difference of the grey levels (0: the same picture; 1: black against white). Small pictures make every pair
cheap (one matrix product for the class), so every pair is a candidate; the SSIM of the two (Wang et al. 2004)
is shown beside it for the person reading.

**Flagging: much closer than usual.** Each student's nearest neighbour distance (exact among their candidates,
estimated otherwise); `typical` is the class's median of them, `spread` the median absolute deviation of their
logarithms (times 1.4826, a standard deviation's size for normal data; at least MIN_SPREAD). A pair is flagged
when its exact distance is at or below `threshold` = typical * min(e^(-K * spread), MAX_SHARE_OF_TYPICAL): far
out from the class's usual on a scale of ratios, and at most half of it (`usual`). With fewer than MIN_CLASS
students compared nothing is flagged: there is no usual to speak of. Plain data in, plain data out: the service
runs `report_files` in a grading process."""

from __future__ import annotations

import hashlib
import json
import math
import statistics
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tracer.grading import canonical as canon
from tracer.grading.metrics import GradingError

BANDS, ROWS = 42, 3  # LSH: 42 bands of 3 rows of the signature
PERMUTATIONS = BANDS * ROWS
PRIME = (1 << 61) - 1  # the hash family (a x + b) mod p, p a Mersenne prime
SEED = 20261207  # the signatures are the same on every run: a report can be made again and compared
MIN_FACTS = 3  # own facts a scene needs to be compared (the starter handed in unchanged says nothing)
COMMON_SHARE, COMMON_MIN = 0.2, 3  # facts that many of the class have are discounted like the starter's
K = 3.0  # how many spreads below the usual a flagged pair is
MIN_SPREAD = 0.1  # a class whose nearest neighbours are all alike still has this much spread (of their logs)
EPSILON = 0.01  # added to a distance before its logarithm (two identical works are at 0)
MAX_SHARE_OF_TYPICAL = 0.5  # and a flagged pair is at most half the usual distance
MIN_CLASS = 5  # students compared, below which there is no usual to compare with
THUMB = 32  # pictures are compared in grey at 32 x 32 (each pixel the mean of its area)
MAX_FACTS_SHOWN = 60  # facts of a flagged pair listed (shared first, then differing)
CLOSEST = 10  # the closest pairs that were not flagged, listed for context
BLOCK = 256  # rows of the estimated distance matrix at a time (memory: BLOCK x n x PERMUTATIONS bytes)

SCENE, IMAGE = "scene", "image"


@dataclass
class Work:
    """One student's submission for the report: their id, its kind (scene, png, exr) and its bytes."""

    student: str
    kind: str
    data: bytes


# -- MinHash --------------------------------------------------------------------------------------


def _coefficients() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(SEED)
    a = rng.integers(1, 1 << 31, PERMUTATIONS, dtype=np.uint64)
    b = rng.integers(0, 1 << 31, PERMUTATIONS, dtype=np.uint64)
    return a, b


A, B = _coefficients()


def fact_hash(fact: str) -> int:
    """A fact as a 32-bit number (so that a x + b stays below 2^64 in unsigned arithmetic)."""
    return int.from_bytes(hashlib.blake2b(fact.encode(), digest_size=4).digest(), "little")


def signature(facts: set[str]) -> np.ndarray:
    """The MinHash signature of a non-empty set: per permutation, the least (a h + b) mod p over its facts."""
    h = np.fromiter((fact_hash(f) for f in facts), dtype=np.uint64, count=len(facts))
    return ((h[:, None] * A[None, :] + B[None, :]) % np.uint64(PRIME)).min(axis=0)


def candidates(keys: list[bytes | np.ndarray], bands: int) -> set[tuple[int, int]]:
    """Pairs (i < j) whose rows agree on every value of some band: `keys[i]` cut into `bands` equal parts."""
    out: set[tuple[int, int]] = set()
    if not keys:
        return out
    width = len(keys[0]) // bands
    for band in range(bands):
        buckets: dict[bytes, list[int]] = defaultdict(list)
        for i, key in enumerate(keys):
            buckets[bytes(key[band * width : (band + 1) * width])].append(i)
        for members in buckets.values():
            for x in range(len(members)):
                for y in range(x + 1, len(members)):
                    out.add((members[x], members[y]))
    return out


def jaccard_distance(a: set, b: set) -> float:
    union = len(a | b)
    return 1.0 - len(a & b) / union if union else 0.0


def estimated_distances(sigs: np.ndarray) -> np.ndarray:
    """1 - the share of signature values two rows agree on: an estimate of every pair's Jaccard distance
    (the diagonal is infinite: no one is their own neighbour)."""
    n = len(sigs)
    out = np.empty((n, n), dtype=np.float32)
    for start in range(0, n, BLOCK):
        block = sigs[start : start + BLOCK]
        out[start : start + BLOCK] = 1.0 - (block[:, None, :] == sigs[None, :, :]).mean(axis=2)
    np.fill_diagonal(out, np.inf)
    return out


# -- images ---------------------------------------------------------------------------------------


def grey(data: bytes, kind: str, size: tuple[int, int]) -> np.ndarray:
    """A PNG or EXR as grey levels in [0, 1] at `size` (width, height), each pixel the mean of its area."""
    from PIL import Image

    from tracer.grading.submission import read_image

    rgb = read_image(data, kind).astype(np.float64)
    if kind == "exr":  # linear radiance: shown as a PNG would be (clamped, a 2.2 gamma)
        rgb = np.clip(rgb, 0.0, 1.0) ** (1 / 2.2)
    y = rgb @ np.array([0.2126, 0.7152, 0.0722])
    im = Image.fromarray(np.clip(y * 255.0, 0, 255).astype(np.uint8), mode="L")
    return np.asarray(im.resize(size, Image.Resampling.BOX), dtype=np.float64) / 255.0


def ssim(x: np.ndarray, y: np.ndarray) -> float:
    """The structural similarity of two grey pictures of one size, over the whole picture (Wang et al. 2004)."""
    c1, c2 = 0.01**2, 0.03**2
    mx, my = x.mean(), y.mean()
    vx, vy, cov = x.var(), y.var(), ((x - mx) * (y - my)).mean()
    return float((2 * mx * my + c1) * (2 * cov + c2) / ((mx**2 + my**2 + c1) * (vx + vy + c2)))


# -- the report -----------------------------------------------------------------------------------


def usual(nearest: list[float]) -> dict:
    """The class's usual nearest-neighbour distance (`typical`, their median), the spread of their logarithms
    (1.4826 times the median absolute deviation, at least MIN_SPREAD), and the `threshold` at or below which a pair
    is flagged: typical / e^(K spread), and at most typical * MAX_SHARE_OF_TYPICAL. On a log scale, as distances
    are compared by their ratio: ten times closer than usual is as telling where the usual is 0.8 as at 0.08."""
    typical = statistics.median(nearest) if nearest else None
    if len(nearest) < MIN_CLASS:
        return {"typical": typical, "spread": None, "threshold": None}
    assert typical is not None, "the median of MIN_CLASS distances or more"
    logs = [math.log(d + EPSILON) for d in nearest]
    centre = statistics.median(logs)
    spread = max(1.4826 * statistics.median(abs(x - centre) for x in logs), MIN_SPREAD)
    threshold = typical * min(math.exp(-K * spread), MAX_SHARE_OF_TYPICAL)
    return {"typical": round(typical, 4), "spread": round(spread, 4), "threshold": round(threshold, 4)}


def _explain(a: canon.Canonical, b: canon.Canonical) -> tuple[list[dict], int]:
    """The two students' own facts side by side: those they share (the evidence), then those that differ
    (a path with two values, or one side's alone)."""
    shared = sorted(set(a.shown) & set(b.shown), key=lambda f: a.shown[f][1])
    rows = [{"path": a.shown[f][1], "a": a.shown[f][2], "b": b.shown[f][2], "shared": True} for f in shared]
    only_a = {a.shown[f][0]: a.shown[f][1:] for f in set(a.shown) - set(b.shown)}  # by path: one row per field
    only_b = {b.shown[f][0]: b.shown[f][1:] for f in set(b.shown) - set(a.shown)}
    for key in sorted(only_a.keys() | only_b.keys(), key=lambda k: (only_a.get(k) or only_b[k])[0]):
        path = (only_a.get(key) or only_b[key])[0]
        in_a, in_b = only_a.get(key, (None, None))[1], only_b.get(key, (None, None))[1]
        rows.append({"path": path, "a": in_a, "b": in_b, "shared": False})
    return rows[:MAX_FACTS_SHOWN], max(0, len(rows) - MAX_FACTS_SHOWN)


def _pairs(kind: str, students: list[str], exact, est: np.ndarray, cands, explain) -> tuple[list, list, dict]:
    """Flagged pairs and the closest others of one kind's group, and its usual."""
    n = len(students)
    d = est.copy()
    exact_d = {}
    for i, j in cands:
        exact_d[(i, j)] = exact(i, j)
        d[i, j] = d[j, i] = exact_d[(i, j)]
    nearest = [float(d[i].min()) for i in range(n)] if n > 1 else []
    stats = usual(nearest)
    flagged, others = [], []
    for (i, j), dist in sorted(exact_d.items(), key=lambda kv: (kv[1], students[kv[0][0]], students[kv[0][1]])):
        pair = {"a": students[i], "b": students[j], "kind": kind, "score": round(dist, 4), "typical": stats["typical"]}
        if stats["threshold"] is not None and dist <= stats["threshold"]:
            facts, more = explain(i, j)
            flagged.append({**pair, "flagged": True, "facts": facts, "facts_more": more})
        elif len(others) < CLOSEST:
            others.append({**pair, "flagged": False})
    return flagged, others, {**stats, "compared": n, "candidates": len(cands)}


def scene_group(works: list[Work], starter: dict | None, skipped: list[dict]):
    given = canon.canonical(starter) if starter is not None else None
    own: list[canon.Canonical] = []
    students: list[str] = []
    for w in works:
        c = canon.read(w.data)
        if c is None:
            skipped.append({"student": w.student, "why": "not a scene (its file is not a JSON object)"})
            continue
        own.append(c.own(given))
        students.append(w.student)
    held: dict[str, int] = defaultdict(int)
    for c in own:
        for f in c.facts:
            held[f] += 1
    common_at = max(COMMON_MIN, math.ceil(COMMON_SHARE * len(own)))
    common = {f for f, k in held.items() if k >= common_at}
    kept, names = [], []
    for student, c in zip(students, own, strict=True):
        c = canon.Canonical(c.facts - common, {f: s for f, s in c.shown.items() if f not in common})
        if len(c.shown) < MIN_FACTS:
            skipped.append({"student": student, "why": f"fewer than {MIN_FACTS} facts of their own beyond the "
                            "starter scene and what much of the class shares: nothing to compare"})  # fmt: skip
            continue
        kept.append(c)
        names.append(student)
    sigs = np.array([signature(c.facts) for c in kept]) if kept else np.zeros((0, PERMUTATIONS), np.uint64)
    cands = candidates([s.view(np.uint8) for s in sigs], BANDS)
    est = estimated_distances(sigs)
    flagged, others, stats = _pairs(
        SCENE, names, lambda i, j: jaccard_distance(kept[i].facts, kept[j].facts), est, cands,
        lambda i, j: _explain(kept[i], kept[j]),
    )  # fmt: skip
    stats["common_facts"] = len(common)
    stats["starter_facts"] = len(given.shown) if given is not None else 0
    return flagged, others, stats


def image_group(works: list[Work], skipped: list[dict]):
    thumbs, names = [], []
    for w in works:
        try:
            thumbs.append(grey(w.data, w.kind, (THUMB, THUMB)))
            names.append(w.student)
        except (GradingError, OSError, ValueError) as e:  # a file the grader could not read: said, not a failure
            skipped.append({"student": w.student, "why": f"its image could not be read: {str(e)[:200]}"})
    flat = np.array(thumbs).reshape(len(thumbs), -1) if thumbs else np.zeros((0, THUMB * THUMB))
    sq = (flat * flat).sum(axis=1)  # every pair at once: |a - b|^2 = |a|^2 + |b|^2 - 2 a.b
    d = np.sqrt(np.maximum(sq[:, None] + sq[None, :] - 2 * flat @ flat.T, 0.0) / max(flat.shape[1], 1))
    np.fill_diagonal(d, np.inf)
    pairs = {(i, j) for i in range(len(flat)) for j in range(i + 1, len(flat))}

    def explain(i: int, j: int) -> tuple[list[dict], int]:
        a, b = thumbs[i], thumbs[j]
        return [
            {"path": f"mean grey level at {THUMB} x {THUMB}", "a": f"{a.mean():.3f}", "b": f"{b.mean():.3f}",
             "shared": abs(a.mean() - b.mean()) < 0.01},
            {"path": f"RMS difference of grey levels at {THUMB} x {THUMB}", "a": f"{d[i, j]:.4f}", "b": "",
             "shared": False},
            {"path": f"SSIM at {THUMB} x {THUMB} in grey (1: the same picture)", "a": f"{ssim(a, b):.3f}", "b": "",
             "shared": False},
        ], 0  # fmt: skip

    return _pairs(IMAGE, names, lambda i, j: float(d[i, j]), d, pairs, explain)


def report(works: list[Work], starter: dict | None = None) -> dict:
    """The class's report: `pairs` (the flagged ones, closest first, each with its facts side by side),
    `closest` (the closest pairs that were not flagged, for context), `groups` (per kind: typical, spread,
    threshold, how many compared and candidates), `skipped` (who was not compared, and why)."""
    skipped: list[dict] = []
    scenes = [w for w in works if w.kind == SCENE]
    images = [w for w in works if w.kind != SCENE]
    pairs, closest, groups = [], [], {}
    for kind, group in ((SCENE, scenes), (IMAGE, images)):
        if not group:
            continue
        flagged, others, stats = scene_group(group, starter, skipped) if kind == SCENE else image_group(group, skipped)
        pairs += flagged
        closest += others
        groups[kind] = stats
    pairs.sort(key=lambda p: (p["score"] / (p["typical"] or 1), p["a"], p["b"]))
    closest.sort(key=lambda p: (p["score"], p["a"], p["b"]))
    return {"students": len(works), "pairs": pairs, "closest": closest[:CLOSEST], "groups": groups,
            "skipped": skipped}  # fmt: skip


def report_files(items: list[tuple[str, str, str]], starter_json: str | None) -> dict:
    """`report` of files on disk: (student, kind, path) each; the starter as JSON text. What a grading process
    runs (plain data in and out)."""
    works = [Work(student, kind, Path(path).read_bytes()) for student, kind, path in items]
    return report(works, json.loads(starter_json) if starter_json else None)
