"""Warnings: settings that have no effect (found from `model_fields_set`), and a few that do something
other than one might expect; each at its JSON path. A scene with warnings is valid."""

from tracer.errors import json_path
from tracer.scene.lights import AREA_LIGHTS, DirectionalLight, PointLight, SpotLight
from tracer.scene.materials import Material
from tracer.scene.model import Scene


def _material_warnings(m: Material, at: list, warn) -> None:
    opaque = not any(m.kt)
    if "ior" in m.model_fields_set and opaque:
        warn([*at, "ior"], "has no effect: the material is opaque (kt = 0)")
    if m.fresnel and opaque and not any(m.kr):
        warn([*at, "fresnel"], "has no effect: the material neither reflects nor transmits (kr = kt = 0)")
    if m.gloss is not None and opaque and not any(m.kr):
        warn([*at, "gloss"], "has no effect: the material neither reflects nor transmits (kr = kt = 0)")
    if max(m.kd) > 1:
        warn([*at, "kd"], "a component > 1 reflects more light than arrives (not energy conserving)")
    _transparency_warnings(m, at, warn)


def _num(v: tuple) -> str:
    """An RGB triple as the student would write it: one number when its three are equal."""
    return f"{v[0]:g}" if v[0] == v[1] == v[2] else "[" + ", ".join(f"{x:g}" for x in v) + "]"


def _transparency_warnings(m: Material, at: list, warn) -> None:
    """Combinations that render something other than the glass, mirror or plastic they were meant to be
    (a first `{"kt": 1, "ior": 1.5}` keeps the default kd 0.5 and comes out a grey, half-opaque ball)."""
    transmits = any(m.kt)
    if transmits and any(m.kd):
        given = "" if "kd" in m.model_fields_set else " (the default)"
        warn(
            [*at, "kd"],
            f"is {_num(m.kd)}{given} while kt = {_num(m.kt)}: the surface is partly diffuse and partly transparent, "
            "so it renders as a grey, half-opaque body, not as glass; clear glass has kd = 0 "
            '(the glass preset: {"kd": 0, "kr": 1, "kt": 1, "ior": 1.5, "fresnel": true})',
        )
    if transmits and not m.fresnel:
        warn(
            [*at, "kt"],
            "transmits without Fresnel: the same share passes at every angle and nothing is reflected at grazing "
            'angles as real glass does; set "fresnel": true and kr = kt for glass',
        )
    if transmits and m.fresnel and m.ior == 1:
        warn([*at, "ior"], "is 1: nothing refracts and Fresnel reflects nothing (R = 0); glass is about 1.5")
    if transmits and m.fresnel and not any(m.kr):
        warn(
            [*at, "kr"],
            "is 0 with Fresnel and kt > 0: the reflected share R is weighted by kr and lost (the body looks dark "
            "at grazing angles and under total internal reflection); glass has kr = kt",
        )
    # what leaves a surface per unit arriving: kd (diffuse albedo) plus the mirror and transmission weights;
    # with Fresnel those two are R·kr and (1 - R)·kt, at most max(kr, kt). The Phong highlight (ks) stands for
    # the mirror image of the point lights and is left out.
    spec = [max(r, t) if m.fresnel else r + t for r, t in zip(m.kr, m.kt, strict=True)]
    total = [d + s for d, s in zip(m.kd, spec, strict=True)]
    if max(total) > 1 + 1e-6 and max(m.kd) <= 1 and not (transmits and any(m.kd)):
        terms = "kd + max(kr, kt)" if m.fresnel else "kd + kr + kt"
        warn(at, f"{terms} = {max(total):g} > 1: reflects more light than arrives (not energy conserving)")


def _warnings(scene: Scene) -> list[dict[str, str]]:
    out: list[dict[str, str]] = []

    def warn(parts: list, message: str) -> None:
        out.append({"path": json_path(parts), "message": message})

    camera, sampler, render = scene.camera, scene.sampler, scene.render
    if "shutter" in camera.model_fields_set and not any(any(o.velocity) for o in scene.objects):
        warn(["camera", "shutter"], "has no effect: nothing moves (no object has a non-zero velocity)")
    if camera.instants is not None:
        if not any(any(o.velocity) for o in scene.objects):
            warn(["camera", "instants"], "has no effect: nothing moves (no object has a non-zero velocity)")
        elif sampler.type != "adaptive" and sampler.spp is not None and sampler.spp % camera.instants:
            warn(
                ["camera", "instants"],
                f"the {camera.instants} instants are not used equally: spp ({sampler.spp}) is not a multiple of it",
            )
    if camera.focus_distance is not None and camera.lens_radius == 0:
        warn(["camera", "focus_distance"], "has no effect with a pinhole camera (lens_radius = 0)")
    if sampler.type != "adaptive":
        for field in ("threshold", "max_level", "jitter"):
            if field in sampler.model_fields_set:
                warn(
                    ["sampler", field],
                    f"has no effect: only the adaptive sampler uses it (type is {sampler.type})",
                )
    if sampler.type == "adaptive":
        if "spp" in sampler.model_fields_set:
            warn(["sampler", "spp"], "has no effect: the adaptive sampler decides how many rays each pixel gets")
        if "filter" in scene.film.model_fields_set:
            warn(["film", "filter"], "has no effect: the adaptive sampler averages its cells (a box filter)")
    solves = render.integrator_info.prepass == "radiosity"  # the radiosity solution, before the render
    if "radiosity" in render.model_fields_set and not solves:
        warn(["render", "radiosity"], f"has no effect: the integrator is {render.integrator}")
    if solves:
        for i, obj in enumerate(scene.objects):
            if any(obj.velocity):
                warn(
                    ["objects", i, "velocity"],
                    "the radiosity solution is solved with every object where it is at time 0: this object's "
                    "light and shadows in it do not move with it (it still blurs in the image)",
                )
    if render.light_samples > 1 and not any(isinstance(light, AREA_LIGHTS) for light in scene.lights):
        warn(["render", "light_samples"], "has no effect: the scene has no area light (quad, disk, sphere)")
    if "color" in scene.fog.model_fields_set and scene.fog.density == 0:
        warn(["fog", "color"], "has no effect: fog density is 0")
    for name, material in scene.materials.items():
        _material_warnings(material, ["materials", name], warn)
    for i, obj in enumerate(scene.objects):
        if isinstance(obj.material, Material):
            _material_warnings(obj.material, ["objects", i, "material"], warn)
    for i, light in enumerate(scene.lights):
        power = "intensity" if isinstance(light, PointLight | SpotLight) else None
        power = power or ("irradiance" if isinstance(light, DirectionalLight) else "radiance")
        if not any(getattr(light, power)):
            warn(["lights", i, power], "is zero: this light contributes nothing")
    return out
