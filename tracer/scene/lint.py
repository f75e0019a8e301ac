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
        elif sampler.type != "adaptive" and sampler.spp % camera.instants:
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
