"""A student's own tracer, explained without a server (`python -m tracer explain`): the probes of their image
against the reference, and, with a tree log, each tree compared with the reference's (explain.py).

The reference is an assignment's reference scene with its settings (as the grader renders it), or a scene file
itself; its mean is rendered here, as the grader renders it (the assignment's reference spp; a scene at its own
sampler and spp).
"""

from __future__ import annotations

import copy
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tracer.grading import metrics
from tracer.grading.explain import Explainer
from tracer.grading.probes import Probe, find, flip_error


@dataclass
class Reference:
    scene: dict  # the reference scene, the assignment's settings applied
    listed: list[dict]  # the spec's own probes
    mean: np.ndarray  # (H, W, 3) linear


def load_reference(path: Path, threads: int | None = None) -> Reference:
    """An assignment (a JSON object with `reference`) or a scene file -> its reference, rendered."""
    from tracer.grading import Grader, load_assignment
    from tracer.grading.renders import InlineRenderer, RenderJob

    data = json.loads(path.read_text(encoding="utf-8"))
    if isinstance(data, dict) and "reference" in data and "camera" not in data:
        assignment, base = load_assignment(path)
        grader = Grader(assignment, base, None)
        if grader.reference is None:
            from tracer.grading import AssignmentError

            raise AssignmentError([{"path": "reference", "message": "this assignment has no reference scene"}])
        (_, _, job), *_ = grader.reference_jobs(set())
        assert assignment.reference is not None, "the grader's reference is the assignment's"
        listed = [p.model_dump() for p in assignment.reference.probes]
        scene = grader.reference.scene
    else:
        from tracer.scene import Limits, load_scene

        load_scene(data)
        scene, listed = data, []
        job = RenderJob("reference", copy.deepcopy(data), 3600.0, Limits(), 10, "the command line")
    rendered = InlineRenderer(threads).one(job)
    if rendered.error:
        raise metrics.GradingError(f"the reference could not be rendered: {rendered.error}")
    assert rendered.image is not None, "a render without an error has its image"
    return Reference(scene, listed, rendered.image)


def probes_of(ref: Reference, shown: np.ndarray) -> list[Probe]:
    """The probes of a student's image (as shown: sRGB floats in [0, 1]) against the reference."""
    exposure = float(ref.scene.get("film", {}).get("exposure", 0.0))
    metrics.same_size(ref.mean, shown)
    return find(flip_error(metrics.display(ref.mean, exposure), shown), ref.listed)


def explain(ref: Reference, shown: np.ndarray, trees: bytes | None) -> dict:
    """{"probes": [...], "trees": [answers]} (trees only with a log)."""
    probes = probes_of(ref, shown)
    out: dict = {"probes": [p.to_json() for p in probes], "trees": []}
    if trees is not None:
        exposure = float(ref.scene.get("film", {}).get("exposure", 0.0))
        ex = Explainer(ref.scene, metrics.display(ref.mean, exposure))
        out["trees"] = ex.compare(trees, shown)
    return out


def text(result: dict) -> str:
    """The result in words, for a terminal."""
    lines = []
    probes = result["probes"]
    if not probes:
        lines.append("probes: none; your image matches the reference everywhere to the eye (FLIP below 0.1)")
    else:
        lines.append(f"probes ({len(probes)}): log the ray tree through the centre of each of these pixels")
        lines += [f"  ({p['x']}, {p['y']}): {p['why']}" for p in probes]
    for a in result["trees"]:
        x, y = a["pixel"]
        if a["matches"]:
            lines.append(f"pixel ({x}, {y}): your tree matches the reference's")
            continue
        lines.append(f"pixel ({x}, {y}): {len(a['differences'])} difference(s), the first one first")
        for d in a["differences"]:
            lines.append(f"  [{d['what']}] (your node {d['student']}, the reference's {d['reference']})")
            lines.append(f"    {d['message']}")
    return "\n".join(lines) + "\n"
