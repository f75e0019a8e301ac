"""Radiosity: energy bookkeeping, a closed box against its analytic radiosity, and the Cornell box
against the path tracer on the diffuse walls."""

import math

import numpy as np
import pytest

from tests.support.scene import scene_dict, small
from tracer.kernels.compile import compile_scene
from tracer.kernels.kinds import RadDisplay
from tracer.kernels.parallel import ITEMS_PER_BAND
from tracer.radiosity import attach, build_patches, solve
from tracer.rendering.progressive import render
from tracer.rendering.raytree import ray_tree
from tracer.scene import SceneError, load_scene


def closed_box(rho: float, le: float):
    """A closed cube of six quads whose fronts face inwards, each emitting radiance le with kd rho."""
    m = {"kd": rho, "emission": le}
    faces = [
        ([-1, -1, -1], [2, 0, 0], [0, 2, 0]),
        ([-1, -1, 1], [0, 2, 0], [2, 0, 0]),
        ([-1, -1, -1], [0, 2, 0], [0, 0, 2]),
        ([1, -1, -1], [0, 0, 2], [0, 2, 0]),
        ([-1, -1, -1], [0, 0, 2], [2, 0, 0]),
        ([-1, 1, -1], [2, 0, 0], [0, 0, 2]),
    ]
    objects = [{"type": "quad", "corner": c, "edge1": a, "edge2": b, "material": m} for c, a, b in faces]
    return load_scene({"camera": {"lookfrom": [0, 0, 0.5], "lookat": [0, 0, 0]}, "objects": objects})[0]


def test_radiosity_patches_cover_the_surfaces():
    scene, _ = load_scene(scene_dict("cornell_path"))
    cs = compile_scene(scene)
    p = build_patches(cs, 0.5)
    n = len(p) // 2
    # 5 walls of 2x2 -> 16 patches each; two boxes -> 6 faces each; both sides of everything
    walls = p.area[:n][p.obj[:n] < 5].sum()
    assert walls == pytest.approx(5 * 4.0, rel=1e-9)
    assert np.allclose(p.normal[:n], -p.normal[n:]) and np.array_equal(p.twin[p.twin], np.arange(len(p)))
    assert (p.emission[n:] == 0).all()


def test_radiosity_energy_is_conserved():
    scene, _ = load_scene(scene_dict("cornell_path"))
    sol = solve(scene, patch_size=0.5, rays=1024, threshold=0.05)
    balance = sol.emitted - sol.absorbed - sol.unshot.sum(axis=0) - sol.escaped
    np.testing.assert_allclose(balance, 0.0, atol=1e-9 * sol.emitted.max())
    assert (sol.escaped > 0).all()  # the box is open towards the camera
    unshot = [h["unshot"] for h in sol.history]
    assert unshot[-1] <= 0.05 * sol.emitted.sum()
    # the unshot energy only falls once the light has shot
    assert all(b <= a + 1e-12 for a, b in zip(unshot[1:], unshot[2:], strict=False))


def test_radiosity_closed_box_matches_the_analytic_value():
    """Every wall emits E = pi le and reflects rho: B = E / (1 - rho) everywhere, nothing escapes."""
    rho, le = 0.6, 1.0
    sol = solve(closed_box(rho, le), patch_size=0.5, rays=2048, threshold=0.002)
    n = len(sol.patches) // 2
    inner = sol.radiosity[:n]  # every face's front side looks into the box
    expected = math.pi * le / (1 - rho)
    assert inner.mean() == pytest.approx(expected, rel=0.02)
    assert np.abs(inner / expected - 1).max() < 0.1  # per patch: Monte Carlo form factors
    assert np.abs(sol.escaped).max() < 1e-3 * sol.emitted.max()


def test_radiosity_cornell_agrees_with_the_path_tracer_on_the_walls():
    width = 48
    data = small(scene_dict("cornell_path"), width, width, sampler={"type": "jittered", "spp": 256})
    scene, _ = load_scene(data)
    cs = compile_scene(scene)
    sol = solve(cs, patch_size=0.25, rays=4096, threshold=0.01)
    img = render(cs).image
    p, n = sol.patches, len(sol.patches) // 2
    cam = scene.camera
    fwd = np.subtract(cam.lookat, cam.lookfrom)
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, cam.vup)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    h = math.tan(math.radians(cam.vfov) / 2)
    rad, path = [], []
    light = scene.lights[0]
    light_centre = np.add(light.corner, np.add(light.edge1, light.edge2) / 2)
    for k, c in enumerate(p.centres()[:n]):
        if p.obj[k] >= 5:  # the walls only (the blocks' faces are small and mostly hidden)
            continue
        if np.linalg.norm(c - light_centre) < 0.6:  # pixels there also see the light itself
            continue
        v = c - np.asarray(cam.lookfrom)
        x = int((np.dot(v, right) / np.dot(v, fwd) / h + 1) * width / 2)
        y = int((1 - np.dot(v, up) / np.dot(v, fwd) / h) * width / 2)
        if not (0 <= x < width and 0 <= y < width):
            continue
        hit = ray_tree(cs, x, y, 0)["nodes"][0]["hit"]
        if hit is None or hit["object"] != p.obj[k]:  # hidden behind a block, or the light
            continue
        side = k if np.dot(p.normal[k], -v) > 0 else k + n
        rad.append(sol.radiosity[side] / math.pi)
        path.append(img[y, x])
    rad, path = np.array(rad), np.array(path)
    assert len(rad) > 100
    # the walls' mean radiance agrees within 5% (patches are flat, the path tracer is noisy)
    np.testing.assert_allclose(rad.mean(axis=0), path.mean(axis=0), rtol=0.05)


@pytest.mark.parametrize("display", ["two-pass", "flat", "smooth"])
def test_radiosity_integrator_matches_the_path_tracer(display):
    """The radiosity integrator's image (each display mode) has the path tracer's mean within 3%."""
    base = small(scene_dict("cornell_path"), 48, 48, sampler={"type": "jittered", "spp": 16})
    rad = dict(
        base,
        render={
            "integrator": "radiosity",
            "max_depth": 3,
            "light_samples": 4,
            "radiosity": {"display": display, "patch_size": 0.34, "rays": 2048},
        },
    )
    path = small(scene_dict("cornell_path"), 48, 48, sampler={"type": "jittered", "spp": 64})
    a = render(load_scene(rad)[0]).image
    b = render(load_scene(path)[0]).image
    assert a.mean() == pytest.approx(b.mean(), rel=0.03)


def test_radiosity_two_pass_ray_tree_takes_interreflection_from_the_solution():
    data = small(
        scene_dict("cornell_path"),
        32,
        32,
        sampler={"type": "center", "spp": 1},
        render={"integrator": "radiosity", "max_depth": 2, "radiosity": {"patch_size": 0.5, "rays": 1024}},
    )
    cs = compile_scene(load_scene(data)[0])
    img = render(cs).image
    tree = ray_tree(cs, 16, 12)  # the back wall
    eye = tree["nodes"][0]
    assert eye["hit"]["object_name"] == "back wall"
    assert min(eye["terms"]["ambient"]) > 0  # the solution's interreflection, in place of ka Ia
    np.testing.assert_allclose(tree["color"], img[12, 16], rtol=1e-5)


# ------------------------------------------------------------------------ curved shapes, the solve as a phase


def shapes_box(patch_size: float = 0.125) -> dict:
    """The Cornell box of scenes/cornell_spheres_radiosity.json (Mitsuba 3's cornell_box() walls and
    light) holding a sphere, a rotated box, a tilted disk and a mesh (icosahedron.ply): every kind
    of surface the solve must mesh."""
    data = scene_dict("cornell_spheres_radiosity")
    data["objects"] = data["objects"][:5] + [
        {"type": "sphere", "name": "sphere", "center": [-0.45, -0.6, -0.35], "radius": 0.35, "material": "white"},
        {
            "type": "box",
            "name": "box",
            "min": [-0.25, 0, -0.25],
            "max": [0.25, 0.5, 0.25],
            "material": "white",
            "transform": {"rotate": [0, -18, 0], "translate": [0.45, -1, 0.3]},
        },
        {
            "type": "disk",
            "name": "disk",
            "center": [0.35, 0.1, -0.5],
            "normal": [-0.3, 0.2, 1],
            "radius": 0.3,
            "material": "white",
        },
        {
            "type": "mesh",
            "name": "icosahedron",
            "file": "icosahedron.ply",
            "material": "white",
            "transform": {"scale": 0.25, "translate": [-0.35, 0.3, 0.2]},
        },
    ]
    data["render"]["radiosity"] = {"patch_size": patch_size, "rays": 2048, "threshold": 0.002, "max_steps": 20000}
    return data


def object_ids(data: dict, width: int) -> np.ndarray:
    """Per pixel, 1 + the index of the object the centre ray sees (0: nothing or a light), and -1 where
    the 3x3 neighbourhood holds another object (edge pixels mix objects in a supersampled image)."""
    d = small(
        data, width, width, sampler={"type": "center", "spp": 1}, render={"integrator": "whitted", "max_depth": 1}
    )
    d["ambient"] = 0
    for i, obj in enumerate(d["objects"]):
        obj["material"] = {"kd": 0, "emission": [i + 1, 0, 0]}
    for light in d["lights"]:
        light["radiance"] = 1000
    ids = np.round(render(load_scene(d)[0]).image[..., 0]).astype(int)
    pad = np.pad(ids, 1, mode="edge")
    same = np.ones_like(ids, dtype=bool)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            same &= pad[dy : dy + width, dx : dx + width] == ids
    return np.where(same, ids, -1)


@pytest.fixture(scope="module")
def shapes_comparison():
    """Region means of the path tracer (256 spp, depth 64) and of the radiosity integrator in each
    display, over the pixels that see each object (one solve, its display switched on the compiled scene)."""
    width = 64
    data = shapes_box()
    ids = object_ids(data, width)
    path = small(
        data, width, width, sampler={"type": "jittered", "spp": 256}, render={"integrator": "path", "max_depth": 64}
    )
    reference = render(load_scene(path)[0]).image
    cs = compile_scene(load_scene(small(data, width, width, sampler={"type": "jittered", "spp": 16}))[0])
    attach(cs)  # solved once; each display below shows the same solution
    names = [o["name"] for o in data["objects"]]
    ratios = {}
    for display in RadDisplay:
        cs.data.rad.mode = int(display)
        img = render(cs).image
        ratios[display] = {}
        for i, name in enumerate(names):
            ours, theirs = img[ids == i + 1].mean(axis=0), reference[ids == i + 1].mean(axis=0)
            ratios[display][name] = (ours.sum() / theirs.sum(), ours / theirs)  # all light, and per channel
    return ratios, cs.radiosity


@pytest.mark.parametrize("display", list(RadDisplay), ids=[d.name.lower() for d in RadDisplay])
def test_radiosity_walls_agree_with_the_path_tracer_around_spheres_disks_boxes_and_meshes(shapes_comparison, display):
    """The walls, floor and ceiling: within 2% of the path tracer in every display (each channel within
    3%: the green wall's red light is a few percent of its light). Before spheres and disks were meshed
    they blocked light and reflected none: 12-15% darker."""
    ratios, _ = shapes_comparison
    for name in ("floor", "ceiling", "back wall", "left wall (red)", "right wall (green)"):
        total, channels = ratios[display][name]
        assert total == pytest.approx(1.0, abs=0.02), name
        np.testing.assert_allclose(channels, 1.0, atol=0.03, err_msg=name)


@pytest.mark.parametrize("display", list(RadDisplay), ids=[d.name.lower() for d in RadDisplay])
def test_radiosity_curved_and_meshed_objects_agree_with_the_path_tracer(shapes_comparison, display):
    """The sphere, box, disk and mesh themselves: within 3% in the two-pass and flat displays (patches of
    0.125 units cannot follow the contact shadows exactly); the smooth display interpolates the
    patches' values at their corners, which carries light into those shadows: within 6%."""
    ratios, _ = shapes_comparison
    tolerance = 0.06 if display == RadDisplay.SMOOTH else 0.03
    for name in ("sphere", "box", "disk", "icosahedron"):
        np.testing.assert_allclose(ratios[display][name][1], 1.0, atol=tolerance, err_msg=name)


def test_radiosity_meshes_every_shape_with_its_true_area():
    data = shapes_box(0.25)
    cs = compile_scene(load_scene(data)[0])
    p = build_patches(cs, 0.25)
    n = len(p) // 2
    front = np.arange(len(p)) < n
    area = {i: p.area[front & (p.obj == i)].sum() for i in range(len(data["objects"]))}
    assert area[5] == pytest.approx(4 * math.pi * 0.35**2, rel=1e-9)  # the sphere, not its inscribed net
    assert area[7] == pytest.approx(math.pi * 0.3**2, rel=1e-9)  # the disk
    assert area[6] == pytest.approx(2 * (0.5 * 0.5) + 4 * (0.5 * 0.5), rel=1e-9)  # the box's six faces
    assert area[8] > 0  # the mesh
    on_sphere = front & (p.obj == 5)
    assert (p.sphere_radius[on_sphere] == 0.35).all() and (
        p.sphere_radius[~on_sphere & front & (p.obj != 5)] == 0
    ).all()
    # the facets' normals face out of the sphere
    centres = p.centres()[on_sphere] - np.asarray(data["objects"][5]["center"])
    assert (np.einsum("ij,ij->i", centres, p.normal[on_sphere]) > 0).all()


def test_radiosity_sphere_in_a_closed_glowing_box_has_the_analytic_radiosity():
    """Every surface emits E = pi le and reflects rho, the sphere too: B = E / (1 - rho) on every wall and
    on the sphere's outside; its inside receives nothing; nothing escapes."""
    rho, le = 0.6, 1.0
    data = closed_box(rho, le).model_dump(exclude_none=True)
    data["objects"].append(
        {"type": "sphere", "center": [0.2, -0.3, 0.1], "radius": 0.4, "material": {"kd": rho, "emission": le}}
    )
    sol = solve(load_scene(data)[0], patch_size=0.25, rays=2048, threshold=0.002, max_steps=20000)
    p, n = sol.patches, len(sol.patches) // 2
    expected = math.pi * le / (1 - rho)
    sphere = p.obj == 6
    outside = np.arange(len(p)) < n
    mean_out = np.average(sol.radiosity[sphere & outside, 0], weights=p.area[sphere & outside])
    assert mean_out == pytest.approx(expected, rel=0.01)
    assert sol.radiosity[sphere & ~outside].max() == 0  # no power leaks through the sphere's surface
    walls = ~sphere & outside
    assert np.average(sol.radiosity[walls, 0], weights=p.area[walls]) == pytest.approx(expected, rel=0.01)
    assert np.abs(sol.escaped).max() < 1e-3 * sol.emitted.max()


def test_radiosity_solve_is_the_same_on_any_number_of_threads():
    scene = load_scene(shapes_box(0.34))[0]
    one = solve(scene, patch_size=0.34, rays=1024, threshold=0.05, threads=1)
    two = solve(scene, patch_size=0.34, rays=1024, threshold=0.05, threads=2)
    three = solve(scene, patch_size=0.34, rays=1024, threshold=0.05, threads=3)
    assert np.array_equal(one.radiosity, two.radiosity) and np.array_equal(one.radiosity, three.radiosity)
    assert [h["shooter"] for h in one.history] == [h["shooter"] for h in three.history]
    # with at least 2 ITEMS_PER_BAND rays a shot, the patches' shots too run in bands on every thread (#17)
    rays = 2 * ITEMS_PER_BAND
    one = solve(scene, patch_size=0.34, rays=rays, threshold=0.05, max_steps=60, threads=1)
    two = solve(scene, patch_size=0.34, rays=rays, threshold=0.05, max_steps=60, threads=2)
    assert len(one.history) > 10
    assert one.rays == two.rays
    assert np.array_equal(one.radiosity, two.radiosity) and np.array_equal(one.unshot, two.unshot)


def test_radiosity_solve_is_a_phase_of_the_render_with_progress_cancel_and_stats():
    data = small(shapes_box(0.34), 24, 24, sampler={"type": "jittered", "spp": 4})
    data["render"]["radiosity"].update(rays=512, threshold=0.05)
    seen = []
    result = render(load_scene(data)[0], progress=seen.append)
    solve_phase = [p for p in seen if p.phase == "radiosity"]
    assert solve_phase and seen.index(solve_phase[-1]) < seen.index(next(p for p in seen if p.phase == "render"))
    fractions = [p.solve["fraction"] for p in solve_phase]
    assert fractions == sorted(fractions) and fractions[-1] == pytest.approx(1.0)
    assert solve_phase[-1].solve["shots"] == result.solve["shots"] > 1
    assert result.rays["radiosity"] == result.solve["rays"] > 0
    assert result.rays["total"] == sum(v for k, v in result.rays.items() if k != "total")
    assert "radiosity solve" in result.stats_line()
    # cancelled during the solve: nothing rendered, and the solve stopped at once
    calls = []

    def cancel() -> bool:
        calls.append(1)
        return len(calls) > 3

    stopped = render(load_scene(data)[0], cancel=cancel)
    assert stopped.cancelled
    assert stopped.spp == 0
    assert len(calls) == 4


def test_radiosity_warns_that_moving_objects_are_solved_at_time_zero():
    data = small(scene_dict("cornell_spheres_radiosity"), 8, 8)
    data["objects"][5]["velocity"] = [0.1, 0, 0]
    _, warnings = load_scene(data)
    assert [w["path"] for w in warnings] == ["objects[5].velocity"]
    assert "time 0" in warnings[0]["message"]


def test_radiosity_needs_surfaces_to_mesh():
    """Every shape is meshed, a lone sphere too; a scene with nothing to mesh is refused at `objects`."""
    sphere = {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"kd": 0.5}}
    camera = {"lookfrom": [0, 0, 5], "lookat": [0, 0, 0]}
    render_settings = {"integrator": "radiosity", "radiosity": {"rays": 64, "threshold": 0.5}}
    scene, _ = load_scene({"camera": camera, "objects": [sphere], "render": render_settings})
    assert len(attach(compile_scene(scene)).patches) > 0
    empty, _ = load_scene({"camera": camera, "render": {"integrator": "radiosity"}})
    with pytest.raises(SceneError) as e:
        attach(compile_scene(empty))
    assert e.value.errors[0]["path"] == "objects"
    assert "needs objects to mesh into patches" in e.value.errors[0]["message"]


def test_radiosity_solutions_are_cached_by_what_they_solve(tmp_path):
    """A second render or ray tree of the same scene reads the solution; another view of it does too; a
    change to what is solved (a wall's colour, the patch size) solves again."""
    from tracer.radiosity import SolutionCache, attach

    cache = SolutionCache(tmp_path / "cache")
    data = small(scene_dict("cornell_radiosity"), 16, 16)
    data["render"]["radiosity"].update(patch_size=0.5, rays=256, threshold=0.05)
    first = compile_scene(load_scene(data)[0])
    solved = attach(first, cache=cache)
    assert not solved.cached and len(list((tmp_path / "cache").glob("*.npz"))) == 1
    moved = small(data, 40, 30, camera={"vfov": 30}, sampler={"type": "center", "spp": 1})  # another view
    again = attach(compile_scene(load_scene(moved)[0]), cache=cache)
    assert again.cached and again.history == solved.history and again.stats()["shots"] == solved.stats()["shots"]
    for name in ("radiosity", "unshot", "direct", "emitted"):
        assert np.array_equal(getattr(again, name), getattr(solved, name)), name
    assert np.array_equal(again.patches.corner, solved.patches.corner)
    assert again.snapshots.keys() == solved.snapshots.keys()
    # the image through the cached solution is the image through the solved one
    cs_a, cs_b = compile_scene(load_scene(data)[0]), compile_scene(load_scene(data)[0])
    attach(cs_a, cache=cache)
    attach(cs_b)
    assert np.array_equal(render(cs_a).image, render(cs_b).image)
    finer = {**data["render"], "radiosity": {**data["render"]["radiosity"], "patch_size": 0.4}}
    for change in ({"materials": {**data["materials"], "red": {"kd": [0.5, 0.1, 0.1]}}}, {"render": finer}):
        other = attach(compile_scene(load_scene({**data, **change})[0]), cache=cache)
        assert not other.cached


def _all_shapes(**radiosity) -> dict:
    """Every shape radiosity meshes (a plane clipped to the scene, a transformed box, a sphere, a disk, a
    triangle, an inline mesh and a mesh file, and a quad), with render.radiosity set to `radiosity`."""
    from tracer.assets import ASSET_DIR  # noqa: F401 (the mesh file is resolved there)

    m = {"kd": 0.5}
    return {
        "camera": {"lookfrom": [0, 1, 6], "lookat": [0, 0, 0]},
        "film": {"width": 8, "height": 8},
        "render": {"integrator": "radiosity", "radiosity": radiosity},
        "lights": [{"type": "quad", "corner": [-0.5, 2.9, -0.5], "edge1": [1, 0, 0], "edge2": [0, 0, 1]}],
        "objects": [
            {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0.2], "material": m},
            {"type": "box", "min": [0, 0, 0], "max": [1, 0.7, 0.3],
             "transform": {"rotate": [10, 30, 0], "scale": [1.3, 1, 2], "translate": [1, -1, 0]}, "material": m},
            {"type": "sphere", "center": [-1, 0, 0], "radius": 0.6, "material": m},
            {"type": "disk", "center": [0, 2, -1], "normal": [0, -1, 0.3], "radius": 0.8, "material": m},
            {"type": "triangle", "vertices": [[0, 0, -2], [1.7, 0.2, -2], [0.3, 1.1, -2.1]], "material": m},
            {"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1.3, 0], [1, 1, 0.2]],
             "faces": [[0, 1, 2], [1, 3, 2]], "transform": {"scale": 0.9, "translate": [-2, 0.5, 1]}, "material": m},
            {"type": "mesh", "file": "icosahedron.ply", "transform": {"scale": 0.5, "translate": [2, 1, -1]},
             "material": m},
            {"type": "quad", "corner": [-3, -1, -3], "edge1": [6, 0, 0], "edge2": [0, 4, 0.5], "material": m},
        ],
    }  # fmt: skip


@pytest.mark.parametrize("patch_size", [0.61, 0.25, 0.13, 0.071])
def test_radiosity_patches_are_counted_before_meshing_as_meshing_makes_them(patch_size):
    """tracer/meshing.py counts each object's patches from its geometry and patch_size alone, as validation
    does (mesh files read from the asset folder), and the count is that of the mesh the solve makes."""
    from tracer import meshing
    from tracer.radiosity import triangles
    from tracer.scene import ASSET_DIR

    scene, _ = load_scene(_all_shapes(patch_size=patch_size), assets=ASSET_DIR)
    counted = meshing.patch_counts(
        scene, patch_size, meshing.mesh_triangles(scene.objects, meshing.mesh_files(ASSET_DIR))
    )
    cs = compile_scene(scene)
    assert counted == meshing.patch_counts(scene, patch_size, triangles(cs))
    p = build_patches(cs, patch_size)
    made = np.bincount(p.obj[: len(p) // 2], minlength=len(scene.objects))
    assert [counted[i] for i in range(len(scene.objects))] == made.tolist()


def test_radiosity_patches_past_the_limit_are_refused_before_meshing():
    """A patch_size that would cut the surfaces into more patches than max_patches is an error at
    render.radiosity.patch_size, in validation and (for a scene validated under other limits) in the solve,
    before a single patch is made: a patch_size of 1e-6 would make 2 x 10^14 of them."""
    from tracer.assets import ASSET_DIR
    from tracer.scene import Limits, validate_scene

    limits = Limits(max_patches=5000)
    errors = validate_scene(_all_shapes(patch_size=1e-6), limits, assets=ASSET_DIR)["errors"]
    assert [e["path"] for e in errors] == ["render.radiosity.patch_size"]
    assert errors[0]["message"].startswith("patches of 1e-06 cut the surfaces into ")
    assert "(objects[0] (plane): 156555204360000, objects[7] (quad): 24186774000000, " in errors[0]["message"]
    assert errors[0]["message"].endswith("must be at most 5000 (limit max_patches): use a larger patch_size")
    scene, _ = load_scene(_all_shapes(patch_size=1e-6), Limits(max_patches=10**15), assets=ASSET_DIR)
    with pytest.raises(SceneError) as info:
        solve(compile_scene(scene, limits=limits), patch_size=1e-6)
    assert info.value.errors[0]["path"] == "render.radiosity.patch_size"
    assert validate_scene(_all_shapes(patch_size=0.25), limits, assets=ASSET_DIR)["valid"]
    other = _all_shapes(patch_size=1e-6)
    other["render"]["integrator"] = "path"  # the settings have no effect (a warning), nor a cost
    assert validate_scene(other, limits, assets=ASSET_DIR)["valid"]


def test_radiosity_rays_times_steps_past_the_limit_are_refused():
    """rays x max_steps bounds the form-factor rays of the longest solve: past max_solve_rays, an error at
    render.radiosity.rays (the default limit is the service's, tracer/limits.py)."""
    from tracer.scene import Limits, validate_scene

    data = _all_shapes(rays=1_000_000, max_steps=100_000)
    most = Limits(max_solve_rays=100_000_000_000)  # every value the fields allow
    assert validate_scene(data, most)["valid"]
    (error,) = validate_scene(data)["errors"]
    assert error == {
        "path": "render.radiosity.rays",
        "message": "rays x max_steps = 1000000 x 100000 = 100000000000 form-factor rays at most; must be at most "
        "250000000 (limit max_solve_rays): use fewer rays or fewer steps",
    }
    with pytest.raises(SceneError) as info:
        solve(compile_scene(load_scene(data, most)[0], limits=Limits(max_solve_rays=10)), rays=4096, max_steps=2000)
    assert info.value.errors[0]["path"] == "render.radiosity.rays"


PACKAGE_MODULES = """
import json, sys
import tracer.rendering.progressive, tracer.rendering.raytree, tracer.integrators.whitted
print(json.dumps(sorted(m for m in sys.modules if m.startswith("tracer.radiosity"))))
"""


def test_radiosity_the_integrators_import_only_the_lookup():
    """A render, a ray tree and the Whitted integrator's code import the one module of the package that their
    kernels call (lookup.py); the solver, the meshing and the cache load only when a scene needs a solution."""
    import json
    import subprocess
    import sys

    from tests.support.scene import ROOT

    p = subprocess.run([sys.executable, "-c", PACKAGE_MODULES], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    assert json.loads(p.stdout.splitlines()[-1]) == ["tracer.radiosity", "tracer.radiosity.lookup"]


def test_radiosity_every_public_name_is_where_the_package_says():
    """The package's names (today's `radiosity.attach`, `radiosity.SolutionCache`, ...) come from their modules."""
    import importlib

    from tracer import radiosity

    for name in radiosity.__all__:
        assert getattr(radiosity, name) is getattr(importlib.import_module(radiosity.HOME[name]), name)
    with pytest.raises(AttributeError):
        radiosity.no_such_name  # noqa: B018
