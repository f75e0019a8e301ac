"""The command line as a user runs it: python -m tracer render | raytree | validate."""

import json
import subprocess
import sys

import numpy as np
from PIL import Image

from tests.support.assets import obj_grid
from tests.support.scene import ROOT, SCENES, scene_dict, small
from tracer.rendering.film import read_exr


def run(*args, check=True):
    p = subprocess.run(
        [sys.executable, "-m", "tracer", *map(str, args)], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    if check and p.returncode != 0:
        raise AssertionError(f"exit {p.returncode}\nstdout: {p.stdout}\nstderr: {p.stderr}")
    return p


def test_cli_render_png_exr_and_statistics(tmp_path):
    out, exr = tmp_path / "w.png", tmp_path / "w.exr"
    p = run(
        "render",
        SCENES / "whitted.json",
        "-o",
        out,
        "--exr",
        exr,
        "--width",
        40,
        "--height",
        30,
        "--spp",
        4,
        "--threads",
        2,
    )
    line = p.stdout.strip().splitlines()[-1]
    assert "Mrays/s" in line
    assert "eye=4800" in line
    assert "shadow=" in line
    png = np.asarray(Image.open(out))
    assert png.shape == (30, 40, 3) and png.std() > 5
    lin = read_exr(exr)
    assert lin.shape == (30, 40, 3)
    assert lin.dtype == np.float32
    # the PNG is the sRGB encoding of the EXR (exposure 0)
    from tracer.rendering.film import to_srgb8

    assert np.array_equal(to_srgb8(lin), png)


def test_cli_render_same_image_for_any_thread_count(tmp_path):
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    for out, threads in ((a, 1), (b, 2)):
        run(
            "render",
            SCENES / "cornell.json",
            "-o",
            tmp_path / "x.png",
            "--exr",
            out,
            "--width",
            24,
            "--height",
            24,
            "--spp",
            4,
            "--threads",
            threads,
        )
    assert np.array_equal(read_exr(a), read_exr(b))


def test_cli_raytree_prints_the_tree(tmp_path):
    f = tmp_path / "s.json"
    f.write_text(json.dumps(small(scene_dict("whitted"), 32, 24)))
    tree = json.loads(run("raytree", f, 22, 14).stdout)
    assert tree["pixel"] == [22, 14]
    assert tree["nodes"][0]["kind"] == "eye"
    assert len(tree["color"]) == 3


def test_cli_raytree_text_one_ray_per_line_indented_by_depth(tmp_path):
    """--text: the tree a person reads, one ray per line (kind, hit, weight, what it carries, why it ended),
    each ray two spaces further in than the ray it came from."""
    f = tmp_path / "s.json"
    f.write_text(json.dumps(small(scene_dict("whitted"), 32, 24)))
    text = run("raytree", f, 9, 13, "--text").stdout  # a pixel of the mirror ball
    tree = json.loads(run("raytree", f, 9, 13).stdout)
    lines = text.splitlines()
    assert lines[0].startswith("pixel (9, 13), sample 0: colour (")
    assert len(lines) == 1 + len(tree["nodes"])  # one line per ray
    eye, shadow, reflection = lines[1], lines[2], lines[3]
    assert eye.startswith("#0 eye ray, depth 1: hit 'mirror ball' (material mirror) at (")
    assert "weight (1, 1, 1)" in eye
    assert "; carries (" in eye
    assert eye.endswith("went on: reflection")
    assert shadow.startswith("  #1 shadow ray to light 0: reached the light; weight (1, 1, 1); carries (")
    assert reflection.startswith("  #2 reflection ray, depth 2: hit 'floor' (material floor)")
    assert "weight (0.85, 0.85, 0.85)" in reflection
    assert "ended: absorbed" in reflection
    assert lines[4].startswith("    #3 shadow ray to light 0: ")  # the floor's shadow ray, one level further in
    # what each line says it carries is the JSON's radiance
    r = tree["nodes"][2]["radiance"]
    assert f"carries ({r[0]:.4g}, {r[1]:.4g}, {r[2]:.4g})" in reflection


def test_cli_validate_good_and_bad(tmp_path):
    assert "valid" in run("validate", SCENES / "whitted.json").stdout
    bad = scene_dict("whitted")
    bad["objects"][1]["radus"] = 2
    bad["objects"][2]["radius"] = -1
    bad["objects"][3]["material"] = "gls"
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(bad))
    p = run("validate", f, check=False)
    assert p.returncode == 1
    assert "objects[1].radus" in p.stderr
    assert "radius" in p.stderr
    assert "objects[2].radius" in p.stderr
    assert "objects[3].material" in p.stderr
    # rendering an invalid scene fails the same way, without a traceback
    p = run("render", f, "-o", tmp_path / "x.png", check=False)
    assert p.returncode == 1
    assert "objects[2].radius" in p.stderr
    assert "Traceback" not in p.stderr
    f.write_text('{"camera": {"lookfrom": [0, 0, 1],}')
    p = run("validate", f, check=False)
    assert p.returncode == 1
    assert "line 1" in p.stderr


def test_cli_errors_name_the_file_line_and_column_of_their_path(tmp_path):
    """Each error at its JSON path's place in the file, `FILE:LINE:COL: error: PATH: MESSAGE`: a member at its key
    (as the page's editor marks it), an unknown field at its own key, a missing field at its object; for
    validate, render and raytree alike, warnings too."""
    text = """{
  "camera": {"lookfrom": [0, 0, 3], "lookat": [0, 0, 0],
             "vfov": -5},
  "materials": {
    "my glass": {"colour": 0.5, "kd": 0.5, "ior": 1.3}
  },
  "objects": [
    {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "my glass"},
      {"type": "sphere", "center": [0, 0, 0], "material": "gls"}
  ]
}
"""
    f = tmp_path / "bad.json"
    f.write_text(text)
    want = [
        f"{f}:3:14: error: camera.vfov: must be > 0",
        f"{f}:5:18: error: materials[\"my glass\"].colour: unknown field 'colour'; did you mean 'kd'?",
        f"{f}:9:47: error: objects[1].material: material 'gls' is not defined in 'materials' (defined: my glass)",
        f"{f}:9:7: error: objects[1].radius: required field 'radius' is missing",
    ]
    for command in (["validate", f], ["render", f, "-o", tmp_path / "x.png"], ["raytree", f, 1, 1]):
        p = run(*command, check=False)
        assert p.returncode == 1 and p.stderr.splitlines() == want, (command, p.stderr)
    text = text.replace('"vfov": -5', '"vfov": 40').replace('"colour": 0.5, ', "").replace('"gls"', '"my glass"')
    f.write_text(text.replace('"material": "my glass"}\n', '"material": "my glass", "radius": 1}\n'))
    p = run("validate", f)
    opaque = "has no effect: the material is opaque (kt = 0)"
    assert p.stderr.splitlines() == [f'{f}:5:29: warning: materials["my glass"].ior: {opaque}']
    f.write_text('{"version": 1,\n "camera": {"vfov": 40,, }\n}')  # a syntax error: at its own line and column
    p = run("validate", f, check=False)
    assert p.returncode == 1 and p.stderr.splitlines()[0].startswith(f"{f}:2:24: error: (scene): invalid JSON at"), p


def test_cli_validate_refuses_what_the_service_refuses(tmp_path, client_without_workers):
    """One table of limits (tracer/limits.py): a 4000 x 3000 film is past max_width and max_height for
    `validate` as for POST /api/validate, with the same errors, each naming its limit."""
    data = scene_dict("whitted")
    data["film"] = {**data.get("film", {}), "width": 4000, "height": 3000}
    report = client_without_workers.post("/api/validate", json={"scene": data}).json()
    assert report["valid"] is False
    assert report["errors"] == [
        {"path": "film.width", "message": "must be at most 2048 (limit max_width)"},
        {"path": "film.height", "message": "must be at most 2048 (limit max_height)"},
    ]
    f = tmp_path / "big.json"
    f.write_text(json.dumps(data))
    p = run("validate", f, check=False)
    assert p.returncode == 1
    text = json.dumps(data)  # one line: each error at its key's column
    at = {e["path"]: text.index(json.dumps(e["path"].split(".")[-1])) + 1 for e in report["errors"]}
    want = [f"{f}:1:{at[e['path']]}: error: {e['path']}: {e['message']}" for e in report["errors"]]
    assert p.stderr.splitlines() == want


def test_cli_renders_radiosity(tmp_path):
    data = small(scene_dict("cornell_path"), 24, 24, sampler={"type": "jittered", "spp": 4})
    data["render"] = {"integrator": "radiosity", "max_depth": 2, "radiosity": {"patch_size": 0.5, "rays": 256}}
    f = tmp_path / "radiosity.json"
    f.write_text(json.dumps(data))
    run("render", f, "-o", tmp_path / "r.png")
    img = np.asarray(Image.open(tmp_path / "r.png"))
    assert img.mean() > 30  # the lit box, not black


def test_cli_render_aovs_into_the_exr(tmp_path):
    import OpenEXR

    out = tmp_path / "a.exr"
    p = run(
        "render",
        SCENES / "antialias_adaptive.json",
        "-o",
        tmp_path / "a.png",
        "--exr",
        out,
        "--aovs",
        "--width",
        40,
        "--height",
        30,
    )
    assert "adaptive to level 3" in p.stdout
    with OpenEXR.File(str(out), separate_channels=True) as f:
        ch = f.channels()
        names = set(ch)
        rays = np.array(ch["rays.Y"].pixels)
    assert {"R", "G", "B", "depth.Z", "rays.Y", "normal.R", "albedo.G", "variance.B"} <= names
    assert rays.min() == 5 and rays.max() > 50  # the sky: the 5 corner and centre rays; edges: many more


def test_cli_validate_resolves_asset_files_like_render(tmp_path):
    """A missing mesh file: `validate` says so (as `render` does), naming the folder and --assets."""
    scene = small(scene_dict("whitted"), 8, 8)
    scene["objects"].append({"type": "mesh", "file": "teapot.obj", "material": {"kd": 0.5}})
    f = tmp_path / "s.json"
    f.write_text(json.dumps(scene))
    mesh_at = json.dumps(scene).rindex('"file"') + 1  # at its key
    error = (
        f"{f}:1:{mesh_at}: error: objects[{len(scene['objects']) - 1}].file: asset file 'teapot.obj' not found in "
        "the asset folder "
        "scenes/assets; copy it there, point the command line at the folder that holds it (--assets DIR), "
        "or embed the file in the scene as a data: URI"
    )
    for command in (["validate", f], ["render", f, "-o", tmp_path / "x.png"], ["raytree", f, 1, 1]):
        p = run(*command, check=False)
        assert p.returncode == 1 and error in p.stderr.splitlines(), (command, p.stderr)
    assets = tmp_path / "assets"
    assets.mkdir()
    (assets / "teapot.obj").write_text(obj_grid(2))
    assert run("validate", f, "--assets", assets).stdout.strip() == f"{f}: valid"


COMMAND_AND_MODULES = """
import json, sys
from tracer.__main__ import main
code = main(sys.argv[1:])
from tracer.integrators import dispatch
print(json.dumps({"code": code, "modules": sorted(m for m in sys.modules if m.startswith("tracer.integrators.")),
                  "kernels": sorted(dispatch._BUILT)}))
"""


def command_modules(*args) -> dict:
    """Run a command in a fresh process: its exit code, the integrator modules it imported and the integrator
    kernels it made (the last line of its standard output)."""
    p = subprocess.run(
        [sys.executable, "-c", COMMAND_AND_MODULES, *map(str, args)], cwd=ROOT, capture_output=True, text=True,
        timeout=300,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout.strip().splitlines()[-1])


def test_cli_a_command_imports_and_loads_only_its_integrators_kernels(tmp_path):
    """Start-up (#17): a Whitted render or ray tree neither imports the path integrator nor defines or
    loads its kernels; a path-traced render makes only the path kernels."""
    whitted = command_modules("render", SCENES / "whitted.json", "-o", tmp_path / "w.png", "--width", 8,
                              "--height", 8, "--spp", 1, "-q")  # fmt: skip
    assert whitted["code"] == 0
    assert whitted["kernels"] == ["whitted"]
    assert "tracer.integrators.path" not in whitted["modules"]
    tree = command_modules("raytree", SCENES / "whitted.json", 100, 100)
    assert tree["code"] == 0
    assert tree["kernels"] == ["whitted"]
    assert "tracer.integrators.path" not in tree["modules"]
    path = command_modules("render", SCENES / "cornell_path.json", "-o", tmp_path / "p.png", "--width", 8,
                           "--height", 8, "--spp", 1, "-q")  # fmt: skip
    assert path["code"] == 0
    assert path["kernels"] == ["path"]


RUN_AS_PROGRAM = """
import gc, json, runpy, sys
full = []
gc.callbacks.append(lambda phase, info: full.append(1) if phase == "stop" and info["generation"] == 2 else None)
sys.argv = ["tracer", *sys.argv[1:]]
try:
    runpy.run_module("tracer", run_name="__main__", alter_sys=True)
except SystemExit as e:
    code = e.code
print(json.dumps({"code": code, "on": gc.isenabled(), "frozen": gc.get_freeze_count(), "full": len(full)}))
"""


def test_cli_starts_without_garbage_collection_then_collects_again(tmp_path):
    """Start-up (#17): python -m tracer render runs no full garbage collection while it imports and loads its
    kernels (each one walks every object made so far: Warp's builtins, the scene models), then turns the
    collector back on with start-up's objects frozen out of it."""
    p = subprocess.run(
        [sys.executable, "-c", RUN_AS_PROGRAM, "render", SCENES / "whitted.json", "-o", tmp_path / "w.png",
         "--width", "8", "--height", "8", "--spp", "1", "-q"], cwd=ROOT, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    state = json.loads(p.stdout.strip().splitlines()[-1])
    assert state["code"] == 0
    assert (tmp_path / "w.png").exists()
    assert state["full"] == 0
    assert state["on"]
    assert state["frozen"] > 100_000
