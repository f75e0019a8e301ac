"""Progressive refinement (Cohen et al. 1988): the patch (or light) with the most unshot power shoots it.

The form factors from the shooter to everything else are estimated by casting rays (Malley's method,
form_factors.py): `rays` points uniformly on the shooter, cosine-weighted directions about its normal, each
carrying an equal share of the power to the first surface it meets. A patch that receives power P keeps
rho P in its radiosity and unshot power, and absorbs (1 - rho) P; area lights are black and absorb what
reaches them; rays that leave the scene (or the meshed part of a plane) take their power out of the
solution ("escaped"). So, exactly at every step:

    emitted = absorbed + unshot + escaped                                  (per RGB channel)

Sources: area lights (power = pi radiance area, shot from points on the light), emissive
materials (a patch's own exitance, pi emission), and point, spot and directional lights, whose
power reaching each patch is computed directly (one shadow ray to the patch centre); for those,
"emitted" counts only the power that reaches a patch.

Units: radiosity B is exitance, W/m^2; power W.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import warp as wp

from tracer.errors import Cancelled
from tracer.kernels.compile import CompiledScene, compile_scene
from tracer.kernels.kinds import Shooter
from tracer.kernels.parallel import BandLauncher, default_threads
from tracer.kernels.structs import empty
from tracer.radiosity.form_factors import TARGET_LIGHT, direct, shoot
from tracer.radiosity.patches import Patches, build_patches, check_limits, patch_index
from tracer.scene import AREA_LIGHTS, Scene

LIGHT_RAYS_PER_PATCH = 256  # an area light shoots at least this many rays per patch side
SNAPSHOT_EVERY_STEP = 16  # snapshots of B after every shot up to this many, then after 32, 64, 128, ...


@dataclass
class Solution:
    patches: Patches
    radiosity: np.ndarray  # (N, 3) B, W/m^2
    unshot: np.ndarray  # (N, 3) unshot power, W
    emitted: np.ndarray  # (3,) W
    absorbed: np.ndarray  # (3,) W
    escaped: np.ndarray  # (3,) W
    history: list[dict] = field(default_factory=list)  # per step: shooter, unshot total, rays
    direct: np.ndarray | None = None  # (N, 3) B once the lights have shot: emitted + directly lit
    snapshots: dict = field(default_factory=dict)  # step -> (N, 3) B after that many shots (see SNAPSHOT_EVERY_STEP)
    threshold: float = 0.01  # the solve stops when unshot < threshold x emitted ...
    max_steps: int = 2000  # ... or after this many shots
    rays: int = 0  # rays cast so far (form factors and the point lights' shadow rays)
    seconds: float = 0.0  # time spent solving so far
    reported: float = 0.0  # the largest fraction() said so far (progress never goes back)
    cached: bool = False  # read from a SolutionCache rather than solved here
    corners: np.ndarray | None = None  # (2 x 3 per patch-mesh triangle, 3) B at the corners (`attach`)
    corners_ind: np.ndarray | None = None  # the same for the interreflected part

    def unshot_total(self) -> float:
        return float(self.unshot.sum())

    def fraction(self) -> float:
        """How far the solve has come, 0..1, never less than said before: the shots against max_steps,
        or the shots so far against the shots to go, estimated from how fast the unshot power has been
        falling over the last quarter of the shots (it falls ever more slowly as it spreads over the
        patches), whichever is further."""
        steps = len(self.history)
        estimate = min(1.0, steps / max(self.max_steps, 1))
        emitted = float(self.emitted.sum())
        left = self.unshot_total() / emitted if emitted > 0 else 1.0
        first = sum(1 for h in self.history if isinstance(h["shooter"], str))  # the lights' shots
        shots = steps - first
        if self.direct is not None and left <= self.threshold:
            estimate = 1.0
        elif self.direct is not None and shots >= 2 and left > 0:
            back = max(1, shots // 4)
            before = self.history[steps - 1 - back]["unshot"] / emitted
            rate = (math.log(max(before, 1e-300)) - math.log(left)) / back  # log of the unshot power, per shot
            if rate > 0:
                estimate = max(estimate, shots / (shots + math.log(left / self.threshold) / rate))
        self.reported = float(min(1.0, max(self.reported, estimate)))
        return self.reported

    def stats(self) -> dict:
        """What the solve cost: shots, rays, seconds, and the share of the power still unshot."""
        emitted = float(self.emitted.sum())
        return {
            "patches": len(self.patches),
            "shots": len(self.history),
            "rays": int(self.rays),
            "seconds": round(self.seconds, 4),
            "unshot": self.unshot_total() / emitted if emitted > 0 else 0.0,
            "cached": self.cached,
        }

    def to_json(self) -> dict:
        """The method made visible: the patch mesh (corner, e1, e2, triangle, normal, area, object;
        sides N/2.. are the backs of 0..N/2), the final radiosity, the energy balance, the convergence
        curve (per shot: who shot, how much, the unshot power left), and snapshots of the radiosity
        after every shot up to 16, then 32, 64, ... and the last. Plain lists, ready for JSON."""
        p = self.patches

        def rows(a: np.ndarray, digits: int = 6) -> list:
            return np.round(np.asarray(a, dtype=np.float64), digits).tolist()

        return {
            "patches": {
                "corner": rows(p.corner),
                "e1": rows(p.e1),
                "e2": rows(p.e2),
                "triangle": p.triangle.tolist(),
                "normal": rows(p.normal),
                "area": rows(p.area),
                "object": p.obj.tolist(),
                "reflectance": rows(p.reflectance),
                "emission": rows(p.emission),
            },
            "radiosity": rows(self.radiosity),
            "energy": {
                "emitted": rows(self.emitted),
                "absorbed": rows(self.absorbed),
                "unshot": rows(self.unshot.sum(axis=0)),
                "escaped": rows(self.escaped),
            },
            "history": self.history,
            "snapshots": {str(k): rows(v) for k, v in sorted(self.snapshots.items())},
            "stats": self.stats(),
        }


def solve(
    scene: Scene | CompiledScene,
    patch_size: float = 0.25,
    rays: int = 4096,
    threshold: float = 0.01,
    max_steps: int = 2000,
    seed: int = 0,
    on_step=None,
    cancel=None,
    threads: int | None = None,
    device: str = "cpu",
) -> Solution:
    """Progressive refinement until the unshot power is below `threshold` of the emitted power (or
    `max_steps` shots). `on_step(solution, step)` is called after each shot; `cancel()` before each
    one (True raises `Cancelled`). The shots' rays run on `threads` threads (default: every core); on a
    CUDA device each shot is one launch."""
    start = time.perf_counter()
    cs = scene if isinstance(scene, CompiledScene) else compile_scene(scene, device=device)
    check_limits(cs, SimpleNamespace(patch_size=patch_size, rays=rays, max_steps=max_steps))
    p = build_patches(cs, patch_size)
    ix, keep = patch_index(p, device)
    n = len(p)
    unshot = p.emission * p.area[:, None]
    sol = Solution(p, p.emission.copy(), unshot, unshot.sum(axis=0), np.zeros(3), np.zeros(3))
    sol.threshold, sol.max_steps = threshold, max_steps
    launch = BandLauncher(threads or default_threads(), device)

    def receive(power_in: np.ndarray) -> None:
        kept = p.reflectance * power_in
        sol.radiosity += kept / p.area[:, None]
        sol.unshot += kept
        sol.absorbed += (power_in - kept).sum(axis=0)

    def shot_done(step: int, entry: dict) -> None:
        sol.history.append({"step": step, **entry, "unshot": sol.unshot_total()})
        sol.seconds = time.perf_counter() - start
        if on_step:
            on_step(sol, step)

    def check_cancel() -> None:
        if cancel is not None and cancel():
            raise Cancelled()

    try:
        step = 0
        # 1. point, spot and directional lights: their power reaching each patch, directly
        points, normals = p.surface_points()
        points = wp.array(points.astype(np.float32), dtype=wp.vec3, device=device)
        normals = wp.array(normals.astype(np.float32), dtype=wp.vec3, device=device)
        received = wp.zeros(n, dtype=wp.vec3, device=device)
        for li, light in enumerate(cs.scene.lights):
            if not isinstance(light, AREA_LIGHTS):
                check_cancel()
                received.zero_()
                launch(direct, n, lambda first, li=li: [cs.data, points, normals, li, first, received])
                power_in = received.numpy().astype(np.float64) * p.area[:, None]
                sol.emitted += power_in.sum(axis=0)
                sol.rays += n
                receive(power_in)
                shot_done(step, {"shooter": f"lights[{li}]"})
                step += 1
        # 2. area lights: shoot their whole power (pi L A)
        for li, light in enumerate(cs.scene.lights):
            if isinstance(light, AREA_LIGHTS):
                check_cancel()
                area = float(cs.data.lights.numpy()[li]["area"])
                power = np.asarray(light.radiance, float) * math.pi * area
                sol.emitted += power
                # the lights' shots make the directly lit part: enough rays for every patch to get its share
                _shoot(
                    sol,
                    cs,
                    ix,
                    launch,
                    Shooter.LIGHT,
                    None,
                    li,
                    seed,
                    step,
                    max(rays, LIGHT_RAYS_PER_PATCH * n),
                    power,
                    receive,
                )
                shot_done(step, {"shooter": f"lights[{li}]"})
                step += 1
        sol.direct = sol.radiosity.copy()
        # 3. progressive refinement: the patch with the most unshot power shoots it
        sol.snapshots[step] = sol.radiosity.copy()
        while step < max_steps and sol.unshot_total() > threshold * float(sol.emitted.sum()):
            check_cancel()
            k = int(np.argmax(sol.unshot.sum(axis=1)))
            power = sol.unshot[k].copy()
            sol.unshot[k] = 0.0
            _shoot(sol, cs, ix, launch, Shooter.PATCH, k, -1, seed, step, rays, power, receive)
            shot_done(step, {"shooter": k, "power": float(power.sum())})
            step += 1
            if step <= SNAPSHOT_EVERY_STEP or step & (step - 1) == 0:  # every early shot, then 32, 64, ...
                sol.snapshots[step] = sol.radiosity.copy()
        sol.snapshots[step] = sol.radiosity.copy()  # and the final solution
    finally:
        launch.close()
    sol.seconds = time.perf_counter() - start
    del keep
    return sol


def _shoot(sol, cs, ix, launch, shooter, k, li, seed, step, rays, power, receive) -> None:
    """One shot of `power` (W, RGB) in `rays` rays from patch side k or area light li."""
    p = sol.patches
    zero = wp.vec3(0.0)
    args = [zero, zero, zero, 0, zero, 0.0]
    if shooter == Shooter.PATCH:
        e1, e2 = (p.e1[k], p.e2[k]) if k < len(p) // 2 else (p.e2[k], p.e1[k])  # a back side: flip its edges
        args = [wp.vec3(*p.corner[k]), wp.vec3(*e1), wp.vec3(*e2), int(p.triangle[k])]
        args += [wp.vec3(*p.sphere_center[k]), float(p.sphere_radius[k])]
    target = empty(rays, dtype=wp.int32, device=launch.device)
    launch(shoot, rays, lambda first: [cs.data, ix, int(shooter), *args, li, seed, step, first, rays, target])
    hits = target.numpy()
    counts = np.bincount(hits[hits >= 0], minlength=len(p))
    share = power / rays
    power_in = counts[:, None] * share[None, :]
    light = int(np.count_nonzero(hits == TARGET_LIGHT))
    escaped = rays - int(counts.sum()) - light
    sol.escaped += escaped * share
    sol.absorbed += light * share
    sol.rays += rays
    receive(power_in)
