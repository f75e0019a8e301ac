"""The scene format reference (docs/scene-format.md) says what the code does, and users can reach it."""

from __future__ import annotations

import json
import re
from pathlib import Path

from tests.support.scene import ROOT, scene_dict, small
from tracer.tools import scene_docs as docs

REFERENCE = ROOT / "docs" / "scene-format.md"


def reference() -> str:
    return REFERENCE.read_text(encoding="utf-8")


def test_docs_field_tables_are_those_of_the_models():
    """`python -m tracer docs` would change nothing: every table is what tracer/scene/ gives."""
    text = reference()
    assert docs.missing(text) == [], "models without a field table"
    assert docs.render(text) == text, "the field tables differ from tracer/scene/: run python -m tracer docs"


def test_docs_check_notices_a_stale_table(tmp_path, capsys):
    stale = tmp_path / "scene-format.md"
    stale.write_text(reference().replace("FULL vertical field of view (degrees).", "vertical angle"), "utf-8")
    assert docs.main(check=True, path=stale) == 1
    assert "differ" in capsys.readouterr().out
    assert docs.main(path=stale) == 0  # rewritten from the models
    assert stale.read_text("utf-8") == reference()


def test_docs_tables_show_types_defaults_and_units():
    camera = docs.table("Camera", {})
    assert "| `vfov` | number > 0 and < 180 | `40` | FULL vertical field of view (degrees). |" in camera
    assert "| `lookfrom` | `[x, y, z]` | required |" in camera
    assert "\\|lookat - lookfrom\\|" in camera  # a | inside a cell is escaped
    sampler = docs.table("Sampler", {"Sampler": "sampler"})
    assert '`"jittered"`' in sampler
    assert "integer from 0 to 8" in sampler
    sphere = docs.table("Sphere", {})
    assert "`velocity`" not in sphere
    assert "`radius`" in sphere  # common fields are in the Object table
    assert "`velocity`" in docs.table("Object", {})


def test_docs_every_link_inside_the_reference_finds_its_heading():
    text = reference()
    anchors = {docs.slug(h) for _, h in docs.HEADING.findall(text)}
    links = set(re.findall(r"\]\(#([^)]+)\)", text))
    assert links and links <= anchors, f"links to no heading: {sorted(links - anchors)}"
    assert len(anchors) == len(docs.HEADING.findall(text)), "two headings with the same anchor"


def test_docs_the_complete_example_is_a_valid_scene_without_warnings():
    from tracer.scene import load_scene

    example = re.search(r"## A complete scene\n.*?```json\n(.*?)```", reference(), re.S)[1]
    scene, warnings = load_scene(json.loads(example))
    assert warnings == []
    assert scene.name == "Two balls"


def test_docs_ray_tree_tables_name_every_field_and_end(compiled_kernels):
    """Every key of a real tree (and every end reason) has a row, and every row is a real key."""
    from tracer.kernels.kinds import End
    from tracer.rendering.raytree import ray_tree
    from tracer.scene import load_scene

    scene, _ = load_scene(small(scene_dict("whitted"), 48, 36))
    tree = ray_tree(scene, 32, 20)  # the glass ball: shadow, reflection and transmission rays
    text = reference()
    fields = text.split("### The tree", 1)[1].split("### Why a ray ends", 1)[0]
    reasons = text.split("### Why a ray ends", 1)[1].split("### An example tree", 1)[0]

    def rows(table: str) -> set[str]:
        found = re.findall(r"^\| `([\w.]+)`(?:, `([\w.]+)`)? \|", table, re.M)
        return {name for row in found for name in row if name}

    hit = next(n["hit"] for n in tree["nodes"] if n["hit"])
    keys = set(tree) | {k for n in tree["nodes"] for k in n} | {f"hit.{k}" for k in hit}
    assert rows(fields) == keys, "the tables and a real tree's keys differ"
    assert rows(reasons) - {"end"} == {e.name.lower() for e in End if e != End.NONE} | {"null"}  # "end": its header


def test_docs_users_are_never_sent_to_a_file_they_do_not_have():
    """README, docs, the page, the API's texts and the code's comments point to docs/scene-format.md, not
    ../shared."""
    files = [ROOT / "README.md", *ROOT.glob("docs/*.md"), *ROOT.glob("web/**/*.*"), *ROOT.glob("server/**/*.py"),
             *ROOT.glob("tracer/**/*.py"), *ROOT.glob("bench/*.py")]  # fmt: skip
    for path in files:
        if path.suffix in (".png", ".jpg"):
            continue
        text = path.read_text(encoding="utf-8")
        for stale in ("../shared", "SCENE_FORMAT.md", "DESIGN.md"):
            assert stale not in text, f"{path.relative_to(ROOT)} mentions {stale}"


CLAIMS_OF_404 = re.compile(r"another token gets a 404|anyone else gets the (very )?404|another token's job alike", re.I)


def test_docs_say_when_another_token_gets_a_404():
    """ "Another token gets a 404" holds on a server with TRACER_INSTRUCTOR_TOKEN, or one not on loopback only:
    on a loopback-only server without it everyone is the instructor (server/core/security.py, get_caller). Each
    sentence that makes the claim states that condition itself."""
    found = 0
    for path in [ROOT / "README.md", *ROOT.glob("docs/*.md"), *ROOT.glob("web/**/*.js"), *ROOT.glob("web/*.html")]:
        text = re.sub(r"\s+", " ", path.read_text(encoding="utf-8"))
        for sentence in re.split(r"(?<=[.!?|])\s+(?=[A-Z*`(|])", text):
            if CLAIMS_OF_404.search(sentence):
                found += 1
                where = f"{path.relative_to(ROOT)}: {sentence[:200]!r}"
                assert "TRACER_INSTRUCTOR_TOKEN" in sentence and "loopback" in sentence, where
    assert found >= 3  # README's, and the routes' and the tokens' sections of docs/service.md


def test_docs_the_readme_links_the_reference():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "](docs/scene-format.md)" in readme
    assert Path(ROOT / "docs" / "scene-format.md").is_file()


def test_docs_the_readme_speaks_to_its_users_before_its_implementers():
    """The README opens with the set-up, then a path each for a student, an instructor and whoever runs it for a
    class; how the renderer works inside (its random numbers, its sequences) is in docs/renderer.md, linked."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    opening = readme[: readme.index("\n## ")]
    for who in ("**If you are a student**", "**If you are an instructor**", "**If you run it for a class**"):
        assert who in opening, who
    for inside in ("PCG", "Sobol", "Owen", "Cranley", "Burley", "@wp.func"):
        assert inside not in readme, f"the README explains {inside}: that is docs/renderer.md's"
        assert inside in (ROOT / "docs" / "renderer.md").read_text(encoding="utf-8"), inside
    assert "](docs/renderer.md)" in readme


def test_docs_the_service_serves_the_reference_as_a_page(client_without_workers):
    client = client_without_workers
    page = client.get("/reference/scene-format.md")
    assert page.status_code == 200
    assert page.headers["content-type"].startswith("text/html")
    html = page.text
    assert '<h2 id="how-a-pixel-is-computed">' in html
    assert '<h3 id="camera-rays">' in html
    assert "<table>" in html
    assert "<code>lookfrom</code>" in html
    assert "&lt;!--" not in html
    assert not re.search(r"(src|href)=\"(https?:)?//", html), "the page loads nothing from other hosts"
    # the page names the server it came from, not the default address the repository's text writes
    base = str(client.base_url).rstrip("/")
    assert f"{base}/reference/scene-format.md" in html
    assert "127.0.0.1:8000" not in html
    other = client.get("/reference/scene-format.md", headers={"host": "localhost:9123"}).text
    assert "http://localhost:9123/reference/scene-format.md" in other
    assert client.get("/css/reference.css").status_code == 200
    listing = client.get("/reference/").text
    for name in ("scene-format.md", "service.md", "web.md", "grading.md"):
        assert f'href="{name}"' in listing
    assert client.get("/reference/nope.md").status_code == 404
    assert client.get("/reference/..%2FREADME.md").status_code == 404
