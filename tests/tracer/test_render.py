"""Renders of every example scene (and of the page's new-scene templates), determinism, and the ray tree
against the image."""

import json

import numpy as np
import pytest
import warp as wp
from numpy.testing import assert_allclose

from tests.support.scene import EXAMPLES, ROOT, scene_dict, small
from tracer.integrators import adaptive
from tracer.kernels.compile import compile_scene
from tracer.rendering.progressive import Renderer, pass_schedule, render, snapshot_bytes, snapshot_from
from tracer.rendering.raytree import ray_tree
from tracer.scene import load_scene
from tracer.tools.pixel_samples import adaptive_count, adaptive_levels


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_render_every_example_scene(path):
    scene, _ = load_scene(small(scene_dict(path.stem), 40, 30, sampler={"type": "jittered", "spp": 4}))
    r = render(scene, threads=2)
    img = r.image
    assert img.shape == (30, 40, 3)
    assert img.dtype == np.float32
    assert np.isfinite(img).all() and (img >= 0).all()
    assert img.mean() > 0.02, "the example renders (almost) black"
    assert img.std() > 0.01, "the example renders a flat colour"
    assert r.rays["eye"] == 40 * 30 * 4
    assert r.rays["total"] == sum(v for k, v in r.rays.items() if k != "total")
    assert ("radiosity" in r.rays) == (scene.render.integrator == "radiosity")  # the solve's rays are counted


@pytest.mark.parametrize("name", ["whitted", "cornell_path"])
def test_render_bit_identical_for_any_thread_count_and_pass_split(name):
    """The same image for any thread count and split of the samples into passes, for the Whitted
    integrator and for the path integrator's shuffled low-discrepancy samples."""
    scene, _ = load_scene(small(scene_dict(name), 48, 40, sampler={"type": "jittered", "spp": 9}))
    cs = compile_scene(scene)
    one = render(cs, threads=1)
    two = render(cs, threads=2)
    three = render(cs, threads=3)
    assert np.array_equal(one.image, two.image) and np.array_equal(one.image, three.image)
    assert one.rays == two.rays
    # the same samples added in other passes: (0..2), (2..9)
    r = Renderer(cs, threads=2)
    r.add_samples(0, 2)
    r.add_samples(2, 9)
    assert np.array_equal(r.image(), one.image)
    # a different seed gives a different image
    other, _ = load_scene(small(scene_dict(name), 48, 40, sampler={"type": "jittered", "spp": 9}, render={"seed": 7}))
    assert not np.array_equal(render(other, threads=2).image, one.image)


def test_render_pass_schedule_covers_samples_once():
    for spp in (1, 2, 16, 17, 100):
        passes = pass_schedule(spp)
        assert passes[0] == (0, 1)
        assert passes[-1][1] == spp
        assert all(a[1] == b[0] for a, b in zip(passes, passes[1:], strict=False))


@pytest.mark.parametrize("name", ["whitted", "cornell", "fog", "bump", "texture", "meshes"])
def test_raytree_color_equals_rendered_sample(name):
    """spp = 1: each pixel is exactly its one sample; the tree's colour must be that sample."""
    scene, _ = load_scene(small(scene_dict(name), 24, 18, sampler={"type": "random", "spp": 1}))
    cs = compile_scene(scene)
    img = render(cs, threads=2).image
    rng = np.random.default_rng(1)
    for x, y in zip(rng.integers(0, 24, 6), rng.integers(0, 18, 6), strict=True):
        tree = ray_tree(cs, int(x), int(y), 0)
        assert_allclose(tree["color"], img[y, x], rtol=1e-5, atol=1e-7)
        # the radiance assembled bottom-up from the nodes is the same value
        assert_allclose(tree["nodes"][0]["radiance"], tree["color"], rtol=1e-4, atol=1e-6)


def test_raytree_samples_average_to_the_pixel():
    scene, _ = load_scene(small(scene_dict("whitted"), 24, 18, sampler={"type": "jittered", "spp": 4}))
    cs = compile_scene(scene)
    img = render(cs, threads=2).image
    for x, y in [(14, 10), (6, 9), (20, 5)]:
        colors = [ray_tree(cs, x, y, k)["color"] for k in range(4)]
        assert_allclose(np.mean(colors, axis=0), img[y, x], rtol=1e-5, atol=1e-7)


def test_raytree_nodes_follow_the_format():
    scene, _ = load_scene(small(scene_dict("whitted"), 64, 48, sampler={"type": "center", "spp": 1}))
    tree = ray_tree(scene, 44, 28)  # the glass ball
    nodes = tree["nodes"]
    assert tree["pixel"] == [44, 28]
    assert tree["sample"] == 0
    assert not tree["truncated"]
    ids = {n["id"] for n in nodes}
    kinds = {n["kind"] for n in nodes}
    assert {"eye", "shadow", "reflection", "transmission"} <= kinds
    assert nodes[0]["kind"] == "eye"
    assert nodes[0]["parent"] is None
    assert nodes[0]["depth"] == 1
    assert nodes[0]["hit"]["object_name"] == "glass ball"
    assert nodes[0]["hit"]["material"] == "glass"
    for n in nodes:
        assert set(n) >= {
            "id",
            "parent",
            "kind",
            "depth",
            "origin",
            "direction",
            "t",
            "hit",
            "weight",
            "radiance",
            "terms",
            "light",
            "occluded",
            "end",
        }
        if n["parent"] is None:
            continue
        assert n["parent"] in ids
        assert n["parent"] < n["id"]
        parent = nodes[n["parent"]]
        if n["kind"] == "shadow":
            assert n["weight"] == parent["weight"]
            assert n["light"] == 0
            assert n["end"] == ("absorbed" if n["occluded"] else "light")
            assert (n["hit"] is None) == (not n["occluded"])
        else:
            # weight = product of K's from the eye; depth one more than the parent's
            assert_allclose(n["weight"], np.multiply(parent["weight"], n["k"]), rtol=1e-6)
            assert n["depth"] == parent["depth"] + 1 <= 5
        if n["t"] is None:
            assert n["hit"] is None
        else:
            assert_allclose(n["hit"]["point"], np.add(n["origin"], np.multiply(n["t"], n["direction"])), atol=1e-4)
            # the shading normal faces the incoming ray
            assert np.dot(n["hit"]["normal"], n["direction"]) <= 1e-6 or n["kind"] == "shadow"


def test_raytree_rejects_pixels_outside_the_film():
    from tracer.scene import SceneError

    scene, _ = load_scene(small(scene_dict("phong"), 8, 6))
    with pytest.raises(SceneError) as e:
        ray_tree(scene, 8, 0, 0)
    assert e.value.errors[0]["path"] == "x"
    with pytest.raises(SceneError):
        ray_tree(scene, 0, 0, 99)


def test_render_passes_refine_and_cancel_keeps_finished_samples():
    scene, _ = load_scene(small(scene_dict("whitted"), 24, 18, sampler={"type": "jittered", "spp": 16}))
    cs = compile_scene(scene)
    seen = []
    full = render(cs, threads=2, on_pass=lambda p: seen.append((p.spp_done, p.image.copy())))
    assert [s for s, _ in seen] == [s1 for _, s1 in pass_schedule(16)]
    assert np.array_equal(seen[-1][1], full.image) and not full.cancelled
    # cancel after the second pass: the image is exactly the 2-sample image
    passes = []
    part = render(cs, threads=2, on_pass=passes.append, cancel=lambda: len(passes) >= 2)
    assert part.cancelled
    assert part.spp == 2
    assert np.array_equal(part.image, seen[1][1])


def adaptive_scene(width: int = 64, height: int = 48, top: int = 3, **sampler):
    scene, _ = load_scene(small(scene_dict("antialias_adaptive"), width, height, sampler={"max_level": top, **sampler}))
    return compile_scene(scene)


def single_passes(cs) -> list[Renderer]:
    """One adaptive pass at each level, each from scratch (a new Renderer)."""
    out = []
    for level in range(cs.data.max_level + 1):
        r = Renderer(cs, threads=2)
        r.adaptive_pass(level)
        out.append(r)
    return out


def pixel_rays(renderers) -> np.ndarray:
    """(level, y, x): the rays of each pixel in a single pass at each level."""
    return np.stack([r.film.counts.numpy().sum(-1).astype(np.int64) for r in renderers])


@pytest.mark.parametrize("jitter", [False, True])
def test_render_adaptive_passes_trace_each_grid_point_once(jitter):
    """#17: an adaptive pass traces only the pixels that the passes before left unfinished (a cell stopped at
    their level limit, not on the threshold), and of those only the grid points of its own level: the colours
    of the points below it are kept from the pass before. Each pass's image, and the rays traced so far, are a
    single pass's at its level, bit for bit; the final image, AOVs and rays are the deepest pass's: the rays of
    all passes together are the rays of that one pass."""
    top = 3
    cs = adaptive_scene(top=top, jitter=jitter)
    previews, snaps, rays_so_far = [], [], []

    def on_pass(p):
        previews.append(p.image.copy())
        snaps.append(snapshot_bytes(p.snapshot()))
        rays_so_far.append(p.rays)

    progressive = render(cs, threads=2, on_pass=on_pass)
    single = single_passes(cs)
    assert all(np.array_equal(previews[level], single[level].image()) for level in range(top + 1))
    assert rays_so_far == [r.rays() for r in single]
    final = single[-1]
    assert np.array_equal(progressive.image, final.image())
    assert all(np.array_equal(progressive.aovs[k], v) for k, v in final.aovs().items())
    assert progressive.rays == final.rays()  # every kind: the passes before the last traced nothing twice
    rays = pixel_rays(single)
    assert (rays[1] > rays[0]).any() and (rays[3] > rays[2]).any(), "some pixels are refined to the last level"
    # resumed after two passes, in another renderer from the snapshot's bytes: the same image; the colours kept
    # are not in the snapshot, so its first pass traces the pixels still unfinished from level 0 again
    snap = snapshot_from(snaps[1])
    resumed = render(cs, threads=1, resume=snap)
    assert np.array_equal(resumed.image, progressive.image)
    again = snap["counts"][snap["done"] == 0].astype(np.int64).sum(axis=0)  # their rays of passes 0 and 1
    assert again.sum() > 0
    kinds = [k for k in progressive.rays if k != "total"]
    assert [resumed.rays[k] for k in kinds] == [progressive.rays[k] + int(n) for k, n in zip(kinds, again, strict=True)]


@pytest.mark.parametrize("keep_bytes", [0, 4000, 40000])
def test_render_adaptive_passes_keep_colours_within_a_bound(keep_bytes):
    """The colours kept from one pass for the next take at most `keep_bytes`: the pixels traced get slots in
    row order while they fit, and a pixel the pass before kept nothing of is traced from level 0 (as every
    pixel was before #17: keep_bytes 0). The images are the same all the same, and the rays counted are the
    rays traced: for each pass, each pixel's rays at that level less, where the pass before kept its colours,
    its rays at the level before."""
    top = 3
    cs = adaptive_scene(top=top)
    single = single_passes(cs)
    rays = pixel_rays(single)
    r = Renderer(cs, threads=2, keep_bytes=keep_bytes)
    expected, kept = 0, np.zeros(rays.shape[1:], bool)
    for level in range(top + 1):
        todo = r.done.numpy() == 0
        r.adaptive_pass(level)
        assert np.array_equal(r.image(), single[level].image())
        expected += int((rays[level] - np.where(kept, rays[level - 1], 0))[todo].sum())
        assert r.rays()["total"] == expected
        fit = keep_bytes // (12 * adaptive.kept_points(level)) if level < top else 0
        kept = np.zeros_like(kept)
        kept.flat[np.flatnonzero(todo)[:fit]] = True  # the slots this pass had: its first pixels traced
        assert r.kept is None if not kept.any() else np.array_equal(r.kept.slots >= 0, kept)
        assert r.kept is None or r.kept.nbytes <= keep_bytes
    assert all(np.array_equal(r.aovs()[k], v) for k, v in single[-1].aovs().items())
    # before #17 every pass traced its pixels from level 0: the counts of the pixels still unfinished, pass by pass
    finished = np.argmax(rays == rays[-1], axis=0)  # a pixel is finished at the first level with its final rays
    old = sum(int(rays[level][finished >= level].sum()) for level in range(top + 1))
    if keep_bytes == 0:
        assert expected == old
    else:
        assert rays[-1].sum() < expected < old


def test_render_adaptive_passes_same_for_any_thread_count_and_band():
    """The kept colours live in per-pixel slots: 1 and 2 threads, and the whole image in one launch, give the
    same images and rays bit for bit."""
    cs = adaptive_scene(80, 60, top=2)
    results = []
    for threads, band in [(1, "auto"), (2, "auto"), (2, 512), (1, None)]:
        r = Renderer(cs, threads=threads, band=band)
        images = []
        for level in range(3):
            r.adaptive_pass(level)
            images.append(r.image())
        results.append((images, r.rays(), r.aovs()))
    first = results[0]
    for images, rays, aovs in results[1:]:
        assert all(np.array_equal(a, b) for a, b in zip(images, first[0], strict=True))
        assert rays == first[1]
        assert all(np.array_equal(aovs[k], v) for k, v in first[2].items())


@wp.kernel(module="test_render_point_slot")
def point_slots(g: int, top: int, out: wp.array2d(dtype=wp.int32)):
    """Level and slot index of every fine-grid point, as the adaptive kernel numbers them."""
    i, j = wp.tid()
    level, index = adaptive.point_slot(i, j, g, top)
    out[j * (g + 1) + i, 0] = level
    out[j * (g + 1) + i, 1] = index


@pytest.mark.parametrize("top", [0, 1, 2, 4])
def test_render_adaptive_point_slots_number_each_level_in_turn(top):
    """The kept colours of a pixel: every grid point a cell uses has a place of its own, at the level of the
    first cells that use it (samples.adaptive_levels), numbered level by level from 0 to kept_points(top)."""
    g = 1 << (top + 1)
    out = wp.zeros(((g + 1) ** 2, 2), dtype=wp.int32)
    wp.launch(point_slots, dim=(g + 1, g + 1), inputs=[g, top, out])
    got = out.numpy()
    levels = adaptive_levels(top)
    assert {k: int(got[k, 0]) for k in levels} == levels
    index = sorted(int(got[k, 1]) for k in levels)
    assert index == list(range(adaptive.kept_points(top)))
    for k, level in levels.items():
        assert adaptive.kept_points(level - 1) <= got[k, 1] < adaptive.kept_points(level)
    assert adaptive.kept_points(top) == adaptive_count(top)


def test_render_stop_and_resume_from_a_snapshot():
    """Stopping early and resuming (in a new Renderer, as another process would) gives the same image
    as one long render: the RNG depends only on (seed, pixel, sample)."""
    scene, _ = load_scene(small(scene_dict("cornell_path"), 24, 24, sampler={"type": "jittered", "spp": 16}))
    cs = compile_scene(scene)
    whole = render(cs, threads=2)
    first = Renderer(cs, threads=1)
    first.add_samples(0, 3)
    snap = first.snapshot()
    later = Renderer(cs, threads=2)
    later.restore(snap)
    later.add_samples(3, 16)
    assert np.array_equal(later.image(), whole.image)
    assert later.rays() == whole.rays


def test_render_a_long_pass_is_cut_into_launches_a_cancel_can_stop_between(monkeypatch):
    """A launch cannot be stopped, so none may be long: the mirror box of issue 24 (each sample up to 2048 rays)
    at 16 x 16 is launched 16 pixels at a time when a launch may trace 16 samples' worth, with progress after
    each; the band callback's exception stops the render after the launch it follows."""
    import json

    import tracer.rendering.progressive as render_module
    from tests.support.scene import ROOT

    box = json.loads((ROOT / "tests" / "tracer" / "mirror_box.json").read_text())
    cs = compile_scene(load_scene(small(box, 16, 16))[0])
    monkeypatch.setattr(render_module, "LAUNCH_RAYS", 2048 * 16)
    monkeypatch.setattr(render_module, "LAUNCH_SECONDS", 1e9)  # cut by the bound on rays alone
    seen = []
    render(cs, threads=1, progress=lambda p: seen.append(p.samples_done))
    assert seen == [16 * k for k in range(1, 17)]

    class Stop(Exception):
        pass

    def stop(p):
        seen.append(p.samples_done)
        raise Stop

    seen.clear()
    for threads in (1, 2):
        with pytest.raises(Stop):
            render(cs, threads=threads, progress=stop, band=64)  # two threads: a band of 64 pixels each
    assert seen == [16, 16]  # one launch's progress each time: the other thread stopped before its next


@pytest.mark.parametrize("name", ["whitted", "antialias_adaptive"])
def test_render_bit_identical_for_any_cut_of_a_pass_into_launches(name, monkeypatch):
    """Launches of a few pixels, or of a few of a pixel's samples, one pixel after the other: the same
    image, the same rays, bit for bit, as whole bands."""
    import tracer.rendering.progressive as render_module

    sampler = {} if name == "antialias_adaptive" else {"sampler": {"type": "jittered", "spp": 9}}
    cs = compile_scene(load_scene(small(scene_dict(name), 40, 30, **sampler))[0])
    whole = render(cs, threads=2)
    most = Renderer(cs).sample_rays * (adaptive.kept_points(cs.data.max_level) if name == "antialias_adaptive" else 1)
    for units in (1, 4, 7):  # 7 units of 9 samples: one pixel, 7 samples then 2
        monkeypatch.setattr(render_module, "LAUNCH_RAYS", most * units)
        for threads in (1, 2):
            cut = render(cs, threads=threads)
            assert np.array_equal(cut.image, whole.image) and cut.rays == whole.rays


TEMPLATES = sorted(p for p in (ROOT / "web" / "templates").glob("*.json") if p.stem != "materials")


@pytest.mark.parametrize("path", TEMPLATES, ids=[p.stem for p in TEMPLATES])
def test_render_every_new_scene_template(path):
    """The page's "New scene" templates (web/templates/) are valid without a warning and render: the empty room
    is its sky alone (nothing in it yet), the others show their walls, balls and light."""
    data = json.loads(path.read_text())
    scene, warnings = load_scene(small(data, 40, 30, sampler={"type": "jittered", "spp": 4}))
    assert warnings == []
    img = render(scene, threads=2).image
    assert np.isfinite(img).all() and img.mean() > 0.02, "the template renders (almost) black"
    if path.stem == "empty_room":
        assert data["objects"] == [] and data["lights"], "an empty room: a light, no objects"
    else:
        assert img.std() > 0.05, "the template renders a flat colour"
