// Lessons: the comparisons the lecture shows, side by side, one click each. Every panel is an example
// scene with a few fields changed, rendered small through the job API; what changed and what it cost
// (rays by kind, time) are written under it. A lesson's controls (sliders and choices bound to scene
// fields) re-render the panels they touch, a moment after the last change, cancelling the jobs they
// supersede. Each lesson ends with a question that the page checks, with an explanation.
import { ApiError, api, blob, showImage } from "./api.js";
import { inspectGroup } from "./inspect.js";
import { followJob } from "./jobs.js";
import { drawSamples, samplerWords } from "./samplers.js";
import { $, clone, debounce, h, integer, num, seconds } from "./util.js";
import { dot, length, normalize, sub } from "./vec.js";

const SIZE = [160, 120]; // the largest lesson image; each keeps its scene's aspect
const SETTLE_MS = 350; // a control's panels re-render this long after its last change
const GLASS_PIXEL = [110, 70]; // on the glass ball of `whitted` at 160 x 120

/** Every material of scene `s` (a name -> material map), `fn(material, name)` each. */
function eachMaterial(s, fn) {
  for (const [name, m] of Object.entries(s.materials || {})) fn(m, name);
}

/** The object of scene `s` called `name`. */
function named(s, name) {
  return (s.objects || []).find((o) => o.name === name);
}

/** A reference panel of the noise lesson: many rays, and another seed than the panels it is compared with (a
 * low-discrepancy panel's points are the first ones of the same seed's longer sequence). */
const REFERENCE = { "sampler.type": "lowdiscrepancy", "sampler.spp": 256, "render.seed": 1 };

/** Choices of a select control from plain values: [[value, text]]. */
const values = (...xs) => xs.map((x) => [x, String(x)]);

export const LESSONS = [
  {
    id: "raytree-stop",
    title: "The ray tree, and when to stop",
    scene: "whitted",
    set: { "sampler.type": "jittered", "sampler.spp": 4 },
    text: "Each eye ray that hits a mirror or glass spawns a reflection ray and a transmission ray, and those spawn their own: a ray tree. A branch ends where its ray leaves the scene, or where it is cut: at max_depth, or where its contribution to the pixel, the product of the K's (kr, kt) along the way, falls below min_weight. Cutting by depth stops every branch at the same generation, bright or faint; cutting by weight stops faint branches early and lets the bright ones (a mirror seen in a mirror) go deep. Compare the pictures and what each cost in rays.",
    controls: [
      { key: "depth", label: "max_depth (left)", kind: "range", min: 1, max: 10, step: 1, value: 2, panels: [0], path: "render.max_depth" },
      { key: "weight", label: "min_weight (right)", kind: "select", choices: values(0.001, 0.05, 0.2, 0.5, 0.9), value: 0.2, panels: [1], path: "render.min_weight" },
    ],
    panels: [
      { label: (s) => `cut at depth ${s.render.max_depth} (min_weight 0)`, set: { "render.min_weight": 0 } },
      { label: (s) => `cut below weight ${s.render.min_weight} (max_depth 10)`, set: { "render.max_depth": 10 } },
    ],
    question: { make: rayTreeQuestion },
  },
  {
    id: "phong",
    title: "The Phong terms: ka·Ia, f_att, kd cos θ, ks cosⁿ φ",
    scene: "phong",
    set: { ambient: 0.3, "render.max_depth": 1 },
    edit: (s) => {
      s.objects = [s.objects[0], { type: "sphere", name: "ball", center: [0, 0.8, 0], radius: 0.8, material: "ball" }];
      s.materials.ball = { kd: [0.2, 0.35, 0.8], ks: 0.5, shininess: 64 };
      s.lights = [{ type: "point", position: [-3, 5, 4], intensity: 60 }];
    },
    text: "The local shading of a hit: I = ka·Ia + f_att·Ip·(kd cos θ + ks cosⁿ φ), with θ between the normal and the light, φ between the mirror direction of the light and the eye, and f_att = 1 / (c1 + c2 d + c3 d²) dimming the point light with its distance d. The three pictures add the terms one at a time; the sliders change the ball's coefficients (and the light's attenuation, which shows best on the floor).",
    controls: [
      { key: "ka", label: "ka (ambient)", kind: "range", min: 0, max: 1, step: 0.05, value: 0.3, apply: (s, v) => (s.materials.ball.ka = v), note: (v) => `ka = ${v}` },
      { key: "kd", label: "kd (diffuse)", kind: "range", min: 0, max: 1, step: 0.05, value: 0.7, apply: (s, v) => (s.materials.ball.kd = [0.3 * v, 0.5 * v, v]), note: (v) => `kd = ${v} × blue` },
      { key: "ks", label: "ks (specular)", kind: "range", min: 0, max: 1, step: 0.05, value: 0.5, apply: (s, v) => (s.materials.ball.ks = v), note: (v) => `ks = ${v}` },
      { key: "n", label: "n (shininess)", kind: "select", choices: values(2, 8, 32, 64, 256, 1024), value: 64, apply: (s, v) => (s.materials.ball.shininess = v), note: (v) => `n = ${v}` },
      {
        key: "att",
        label: "f_att",
        kind: "select",
        choices: [
          [[0, 0, 1], "1 / d² (inverse square)"],
          [[0, 7, 0], "1 / 7d (linear)"],
          [[50, 0, 0], "1 / 50 (constant)"],
        ],
        value: [0, 0, 1],
        apply: (s, v) => (s.lights[0].attenuation = v),
        note: (v) => `attenuation = ${JSON.stringify(v)}`,
      },
    ],
    panels: [
      { label: "ambient only: ka·Ia", edit: (s) => Object.assign(s.materials.ball, { kd: 0, ks: 0 }), note: "kd = ks = 0" },
      { label: "+ diffuse: f_att·Ip·kd cos θ", edit: (s) => Object.assign(s.materials.ball, { ks: 0 }), note: "ks = 0" },
      { label: "+ specular: f_att·Ip·ks cosⁿ φ (Phong)" },
    ],
    question: {
      prompt: "Raise n, the shininess. What does the highlight on the right-hand picture do?",
      choices: ["It grows larger and dimmer", "It shrinks to a smaller, sharper spot", "It moves across the ball", "It takes the ball's colour"],
      answer: 1,
      explain: "cosⁿ φ falls off faster the larger n is, so only directions very close to the mirror direction of the light stay bright: a small, sharp highlight (a polished surface). A small n gives a broad, soft one. The highlight keeps the light's colour, since ks is white here.",
    },
  },
  {
    id: "bounces",
    title: "Ray casting vs 2 vs 3 bounces",
    scene: "whitted",
    set: { "sampler.type": "jittered", "sampler.spp": 4 },
    text: "max_depth counts bounces of light on the way to the eye. With 1 (ray casting) the mirror and the glass show only their own Phong shading; with 2 the mirror reflects the scene but the glass ball is dark inside, because the transmitted ray is cut before it can leave the ball; with 3 the refracted floor appears through the glass.",
    controls: [{ key: "kr", label: "the mirror ball's kr (no effect on ray casting)", kind: "range", min: 0, max: 1, step: 0.05, value: 0.85, panels: [1, 2], path: "materials.mirror.kr" }],
    panels: [
      { label: "ray casting (1 bounce)", set: { "render.max_depth": 1 } },
      { label: "ray tracing, 2 bounces", set: { "render.max_depth": 2 } },
      { label: "ray tracing, 3 bounces", set: { "render.max_depth": 3 } },
    ],
    question: {
      prompt: "With 2 bounces, why is the glass ball dark inside?",
      choices: ["The glass absorbs the light", "The transmitted ray enters the ball at depth 2 and is cut before it can leave it", "Its shadow rays are blocked by the glass", "Glass has no diffuse colour, so nothing is seen through it"],
      answer: 1,
      explain: "The eye ray (depth 1) hits the ball and spawns a transmission ray (depth 2), which meets the ball's far side from inside. Leaving the ball needs one more transmission ray, at depth 3: with max_depth 2 it is not traced, so that branch brings back nothing but the local shading (black: kd = 0).",
    },
  },
  {
    id: "sampling",
    title: "One ray per pixel vs supersampling vs adaptive vs jittered",
    samples: [44, 37], // the pixel whose samples are drawn (at 160 x 120): the ball's edge against the sky crosses it
    text: "The same scene sampled four ways; under each, where the sampler puts its rays inside one pixel. One ray per pixel gives jaggies, broken thin poles and moiré near the horizon (a frequency too high for the pixels masquerading as a lower one). A regular grid smooths edges but the moiré only moves. Adaptive supersampling starts from the corners and the centre and splits only cells whose colours differ (here across an edge). Jittered sampling (one random point per cell) turns the moiré into noise; how much noise depends on how evenly the points lie (the noise lesson compares random, jittered and low-discrepancy points).",
    controls: [{ key: "spp", label: "rays per pixel (grid and jittered)", kind: "select", choices: values(4, 16, 64), value: 16, panels: [1, 3], path: "sampler.spp" }],
    panels: [
      { label: "one ray per pixel (center)", scene: "antialias_center" },
      { label: (s) => `supersampling: ${Math.sqrt(s.sampler.spp)} × ${Math.sqrt(s.sampler.spp)} grid`, scene: "antialias_grid" },
      { label: "adaptive supersampling", scene: "antialias_adaptive" },
      { label: (s) => `stochastic: jittered ${Math.sqrt(s.sampler.spp)} × ${Math.sqrt(s.sampler.spp)}`, scene: "antialias_jittered" },
    ],
    question: {
      prompt: "Which picture turns the moiré of the checkered floor near the horizon into noise?",
      choices: ["one ray per pixel", "the regular grid", "adaptive supersampling", "jittered sampling"],
      answer: 3,
      explain: "Regular samples (one per pixel, a grid, or the adaptive sampler's grid points) line up with the regular checks and alias them into false patterns. Jittered samples are random inside their cells: the error no longer repeats from pixel to pixel, so the eye sees fine noise instead of a pattern, and more rays make that noise smaller.",
    },
  },
  {
    id: "aliasing",
    title: "Adaptive supersampling: where the rays go",
    scene: "antialias_adaptive",
    raysMap: true,
    text: "The adaptive sampler traces the 4 corners and the centre of each pixel; where those colours differ by more than the threshold the pixel is cut into 4 cells, each sampled the same way, down to max_level. Under each picture, its rays per pixel (white: many). The rays gather on edges and the poles, but a cell can look uniform while it spans several checks of the floor near the horizon: there the sampling grid meets a regular structure and still aliases. Adaptive stochastic sampling (jitter) moves the grid points at random inside their cells, which turns that aliasing into noise.",
    controls: [
      { key: "threshold", label: "threshold", kind: "select", choices: values(0.01, 0.05, 0.1, 0.3), value: 0.05, panels: [0, 1], path: "sampler.threshold" },
      { key: "level", label: "max_level", kind: "range", min: 1, max: 4, step: 1, value: 3, panels: [0, 1], path: "sampler.max_level" },
    ],
    panels: [
      { label: "adaptive supersampling" },
      { label: "adaptive stochastic (jitter)", set: { "sampler.jitter": true } },
      { label: "picture A", reveal: "picture A: jittered, 16 rays in every pixel", scene: "antialias_jittered" },
      { label: "picture B", reveal: "picture B: adaptive, threshold 0.1", set: { "sampler.threshold": 0.1 } },
    ],
    question: {
      prompt: "Pictures A and B were made by two different samplers. Which one used the adaptive sampler? (Look at their rays per pixel.)",
      choices: ["picture A", "picture B"],
      answer: 1,
      explain: "B's count changes from pixel to pixel: many rays along the edges of the ball, the poles and the checks, few in flat regions; only the adaptive sampler does that. A's map has just two flat levels: 16 eye rays in every pixel, plus a shadow ray for each one that hits something (the sky has none). That is a fixed-rate sampler, here jittered.",
    },
  },
  {
    id: "temporal",
    title: "Temporal aliasing: instants vs a time per ray",
    scene: "temporal",
    set: { "sampler.type": "jittered" },
    text: "Time is sampled too. A single instant shows a fast ball frozen (a strobe). Averaging N instants (frames at 120 Hz averaged into one, camera.instants = N) shows N separate copies: the time samples are regular, so fast motion aliases. Giving every ray its own random time in the shutter (distributed ray tracing) makes one continuous streak, noisy where there are few rays. All three pictures cost the same number of rays.",
    controls: [
      { key: "n", label: "instants N (middle)", kind: "select", choices: values(2, 4, 8), value: 4, panels: [1], path: "camera.instants" },
      { key: "spp", label: "rays per pixel (all)", kind: "select", choices: values(4, 16, 64), value: 16, path: "sampler.spp" },
    ],
    panels: [
      { label: "one instant (a still frame)", set: { "camera.instants": 1 } },
      { label: (s) => `${s.camera.instants} instants averaged` },
      { label: "a random time per ray", set: { "camera.instants": null } },
    ],
    question: {
      prompt: "At the same cost, which picture shows the moving ball as separate copies?",
      choices: ["one instant", "N instants averaged", "a random time per ray"],
      answer: 1,
      explain: "Averaging N instants samples time at N regular points: the ball is seen at N places and nowhere between, a strobe (temporal aliasing). One instant shows one sharp ball and no motion at all. A random time per ray covers the whole shutter interval, so the copies melt into a streak; too few rays leave noise instead of copies.",
    },
  },
  {
    id: "motion",
    title: "Motion blur: the object, its shadow, its reflection",
    scene: "motion_blur",
    set: { "sampler.spp": 16 },
    text: "Each eye ray gets its own time while the shutter is open, and moving objects are where they are at that time; the shadow and reflection rays it spawns share that time. So the moving ball blurs, and so do its shadow on the floor and its image in the mirror behind. The still version is the same scene with every velocity removed.",
    controls: [
      {
        key: "speed",
        label: "the red ball's speed",
        kind: "range",
        min: 0,
        max: 2.4,
        step: 0.2,
        value: 0.8,
        panels: [1],
        apply: (s, v) => (named(s, "moving ball").velocity = [v, 0, 0]),
        note: (v) => `moving ball's velocity = [${v}, 0, 0]`,
      },
    ],
    panels: [
      { label: "still (velocities removed)", edit: (s) => (s.objects || []).forEach((o) => delete o.velocity), note: "objects[*].velocity removed" },
      { label: (s) => `moving, shutter open ${(s.camera.shutter || [0, 1]).join(" → ")}` },
    ],
    question: {
      prompt: "In the moving picture, what blurs?",
      choices: ["only the red ball", "the red ball and its shadow", "the red ball, its shadow and its reflection in the mirror"],
      answer: 2,
      explain: "A shadow ray and a reflection ray carry the time of the eye ray that spawned them, so they meet the ball where it was at that time: the shadow and the mirror image are averaged over the shutter interval as well. Only the still blue ball, and what it casts, stays sharp.",
    },
  },
  {
    id: "glossy",
    title: "Glossy reflection: a cone of rays",
    scene: "glossy",
    set: { "sampler.spp": 16 },
    text: "A perfect mirror sends one reflection ray. A glossy surface sends reflection rays in a cone around the mirror direction, narrower the larger the material's gloss m (a cos^m lobe, like the Phong exponent): averaged over the pixel's rays, the reflections of the other objects blur. The left ball's m is the slider; the others keep theirs (300, 40, and frosted glass 150). Fewer rays per pixel: a noisier blur.",
    controls: [
      { key: "m", label: "gloss m (left ball)", kind: "select", choices: values(10, 40, 150, 600, 3000), value: 40, panels: [1], path: "materials.mirror.gloss" },
      { key: "spp", label: "rays per pixel", kind: "select", choices: values(4, 16, 64), value: 16, path: "sampler.spp" },
    ],
    panels: [
      { label: "perfect mirrors: one reflection ray", edit: (s) => eachMaterial(s, (m) => delete m.gloss), note: "every gloss removed" },
      { label: (s) => `glossy: a cone of rays, left ball m = ${s.materials.mirror.gloss}` },
    ],
    question: {
      prompt: "A glossy ball shows a fuzzy highlight of the lamp. Does that highlight light up the floor next to the ball?",
      choices: ["Yes, the floor gets brighter under it", "No: a highlight is only the ball's local term, and the floor sends no rays towards the ball to pick it up"],
      answer: 1,
      explain: "The highlight ks cosⁿ φ is computed at the ball for the eye's direction; it is not light that leaves the ball towards other objects. The diffuse floor gathers light only through its shadow rays to the lamp. Only a reflection ray (from a mirror, or a glossy cone sampled stochastically) sees other objects, which is why glossy reflections of the orange block blur while the lamp's light on the floor does not change.",
    },
  },
  {
    id: "shadows",
    title: "Hard vs soft shadows",
    set: { "sampler.type": "jittered", "sampler.spp": 4 },
    text: "A point light casts hard shadows: a point is lit or not. An area light is sampled with light_samples shadow rays to random points of the light per shading point: the fraction that reaches the light makes the penumbra. Fewer rays, more noise; more rays, less noise (and more shadow rays to pay for). The penumbra is widest where the shadow is far from the object that casts it.",
    controls: [{ key: "light", label: "shadow rays per point (right)", kind: "range", min: 1, max: 32, step: 1, value: 16, panels: [2], path: "render.light_samples" }],
    panels: [
      { label: "point light: hard shadows", scene: "cornell" },
      { label: "area light, 1 shadow ray", scene: "cornell_whitted_area", set: { "render.light_samples": 1 } },
      { label: (s) => `area light, ${s.render.light_samples} shadow rays`, scene: "cornell_whitted_area" },
    ],
    question: {
      prompt: "Where is the penumbra of a block's shadow widest?",
      choices: ["right where the block stands on the floor", "far from the block, at the shadow's far edge", "it has the same width everywhere"],
      answer: 1,
      explain: "By similar triangles: the penumbra's width is the light's size times (distance from the occluding edge to the floor) / (distance from the light to that edge). Where the block touches the floor that distance is 0 and the shadow is sharp; it widens with distance from the block.",
    },
  },
  {
    id: "dof",
    title: "Pinhole vs depth of field",
    scene: "depth_of_field",
    set: { "sampler.spp": 16 },
    coc: true,
    text: "A pinhole camera sends every eye ray through one point: everything is sharp. A thin lens starts eye rays at random points of the lens, all through the point where the pinhole ray meets the focal plane: objects on that plane stay sharp, the others blur in proportion to their distance from it. Click a point of either picture: its circle of confusion (the disk a point at that depth spreads into) is drawn on the lens picture, from the thin-lens formula.",
    controls: [
      { key: "radius", label: "lens radius", kind: "range", min: 0, max: 0.4, step: 0.01, value: 0.15, panels: [1], path: "camera.lens_radius" },
      { key: "focus", label: "focus distance", kind: "range", min: 3, max: 13, step: 0.1, value: 7.3, panels: [1], path: "camera.focus_distance" },
    ],
    panels: [
      { label: "pinhole", set: { "camera.lens_radius": 0 } },
      { label: (s) => `thin lens, radius ${s.camera.lens_radius}, focused at ${s.camera.focus_distance ?? "lookat"}` },
    ],
    question: {
      prompt: "The lens focuses 7.3 units in front of it, on the green ball. Which ball has the largest circle of confusion?",
      choices: ["the near red ball (about 4 units away)", "the green ball", "the far blue ball (about 11.7 units away)"],
      answer: 0,
      explain: "The circle's diameter on the film grows with |1 − F/z| for a point at depth z and focus distance F: 0.84 for the red ball (z ≈ 4.0), 0.01 for the green one, 0.37 for the blue one (z ≈ 11.7). In front of the focal plane the blur grows fast, behind it slowly (it tends to the lens's size as z goes to infinity).",
    },
  },
  {
    id: "integrators",
    title: "Diffuse interreflection: Whitted + ambient vs path tracing vs radiosity",
    scene: "cornell_path",
    set: { "sampler.spp": 16 },
    text: "The same Cornell box and ceiling light. Whitted's ray tree follows only mirror and refraction rays: soft shadows from the area light, but light does not bounce between walls; its ambient term (ka·Ia, the slider) fakes the missing light with one constant. The path tracer samples diffuse bounces too: red and green bleed onto the white blocks and the ceiling is lit. Radiosity solves diffuse interreflection between the diffuse surfaces first (patches and form factors), then traces the ray tree for direct light and mirrors.",
    controls: [{ key: "ambient", label: "Whitted's ambient Ia", kind: "range", min: 0, max: 0.5, step: 0.05, value: 0, panels: [0], path: "ambient" }],
    panels: [
      { label: (s) => `Whitted ray tracing, ambient ${s.ambient}`, set: { "render.integrator": "whitted" } },
      { label: "path tracing", set: { "render.integrator": "path" } },
      { label: "radiosity", set: { "render.integrator": "radiosity" } },
    ],
    question: {
      prompt: "Why is the ceiling dark in the Whitted picture, but lit in the other two?",
      choices: ["The ceiling's material is black", "The light faces down: the ceiling gets only light bounced off the walls, which Whitted's tree does not follow", "Whitted's picture has too few rays per pixel"],
      answer: 1,
      explain: "The ceiling light emits downwards, so no shadow ray from the ceiling reaches its bright side. All the ceiling's light comes from other surfaces: diffuse interreflection. Path tracing follows it with random diffuse bounces, radiosity with form factors between patches; Whitted's ambient term only adds the same constant everywhere.",
    },
  },
  {
    id: "noise",
    title: "Noise: random vs jittered vs low-discrepancy (quasi-Monte Carlo)",
    samples: [44, 37], // the pixel whose samples are drawn (at 160 x 120 and 120 x 120)
    text: "A pixel's colour is an average (over its area, and over the lens, the shutter and a path's bounces) estimated from a few rays: the estimate is off by a random error, the noise. How the rays' points are spread changes that error, not the picture they converge to. Random: independent points, which clump and leave gaps. Jittered: one random point in each cell of a √n × √n grid (stratified). Low-discrepancy (quasi-Monte Carlo): the successive points of a Sobol sequence, scrambled for each pixel; every first 2ᵏ of them form a (0,k,2)-net, one point in each box of area 2⁻ᵏ: at 16 rays one in each of the 4 × 4 cells, and also one in each of 16 thin columns and 16 thin rows. The sampler chooses only where a ray crosses the pixel (and the lens, and the shutter time); a path's bounce directions and its points on the light come from the path's own points, the same for all three. Under each picture: one pixel's rays, and the RMS difference from the row's reference (256 rays per pixel, another seed; its own small noise counts too). Top: ray tracing with a point light. Bottom: the path-traced Cornell box.",
    controls: [{ key: "spp", label: "rays per pixel (all but the references)", kind: "select", choices: values(4, 16, 64), value: 16, panels: [0, 1, 2, 4, 5, 6], path: "sampler.spp" }],
    panels: [
      { label: (s) => `random, ${s.sampler.spp} rays`, scene: "antialias_jittered", set: { "sampler.type": "random" }, against: 3 },
      { label: (s) => `jittered, ${s.sampler.spp} rays (${Math.sqrt(s.sampler.spp)} × ${Math.sqrt(s.sampler.spp)} cells)`, scene: "antialias_jittered", set: { "sampler.type": "jittered" }, against: 3 },
      { label: (s) => `low-discrepancy, ${s.sampler.spp} rays`, scene: "antialias_jittered", set: { "sampler.type": "lowdiscrepancy" }, against: 3 },
      { label: "reference: low-discrepancy, 256 rays", scene: "antialias_jittered", set: REFERENCE, samples: null },
      { label: (s) => `path traced, random, ${s.sampler.spp} rays`, scene: "cornell_path", set: { "sampler.type": "random" }, against: 7 },
      { label: (s) => `path traced, jittered, ${s.sampler.spp} rays (${Math.sqrt(s.sampler.spp)} × ${Math.sqrt(s.sampler.spp)} cells)`, scene: "cornell_path", set: { "sampler.type": "jittered" }, against: 7 },
      { label: (s) => `path traced, low-discrepancy, ${s.sampler.spp} rays`, scene: "cornell_path", set: { "sampler.type": "lowdiscrepancy" }, against: 7 },
      { label: "path traced reference: low-discrepancy, 256 rays", scene: "cornell_path", set: REFERENCE, samples: null },
    ],
    question: {
      prompt: "At the same number of rays, the low-discrepancy picture of the floor is the closest to its reference and the random one the farthest. Yet on the path-traced Cornell box the three are about equally far from theirs. Why?",
      choices: [
        "Low-discrepancy points only work for ray tracing with a point light",
        "The sampler chooses only where each ray crosses the pixel; most of the box's noise comes from the bounce directions and the points on the light, which are the same for all three",
        "The Cornell box was rendered with fewer rays per pixel",
        "The path tracer averages the three samplers together",
      ],
      answer: 1,
      explain: "On the floor, the film position is the only random choice, and a pixel's error comes from the edges (of the checks, the ball, the poles) that cross it. Random points leave gaps and clumps, so the error of their average falls only as 1/√n: 4 times the rays, half the noise. Stratification puts one point in each cell, so only the cells an edge crosses contribute to the error, and it falls faster. A (0,k,2)-net is stratified in every shape at once (4 × 4 cells, 2 × 8, 16 thin columns, 16 thin rows), so an edge at any angle is met evenly; and every first 2ᵏ points are such a net, so a progressive render is even at each pass. In the box most pixels see no edge: their noise is the choice of each bounce's direction and of a point on the light, and changing where the rays cross the pixel does not change it; only the few pixels on an edge gain. The renderer's bounces already take their own low-discrepancy points, whatever the sampler.",
    },
  },
  {
    id: "radiosity",
    title: "Radiosity: flat vs smooth vs two-pass",
    scene: "cornell_radiosity",
    set: { "sampler.spp": 4, "render.light_samples": 2, "render.radiosity.rays": 1024 },
    stepper: true,
    text: "Radiosity cuts the diffuse surfaces into patches and solves how much light each patch sends to every other (form factors), by progressive refinement: the brightest patch shoots its unshot power, again and again. Flat shows each patch's radiosity as it is, tiles and all; smooth interpolates it from the patch corners (Gouraud); two-pass adds a ray-tracing pass that computes direct light, shadows and mirrors per pixel and takes only the light bounced between surfaces from the patches. “Step through the shooting” opens a panel's job in the workspace, where the radiosity view replays the shots one by one.",
    controls: [{ key: "patch", label: "patch size", kind: "select", choices: values(0.5, 0.35, 0.25), value: 0.35, path: "render.radiosity.patch_size" }],
    panels: [
      { label: "flat: one colour per patch", set: { "render.radiosity.display": "flat" } },
      { label: "smooth: interpolated", set: { "render.radiosity.display": "smooth" } },
      { label: "two-pass: radiosity + ray tracing", set: { "render.radiosity.display": "two-pass" } },
    ],
    question: {
      prompt: "Why are the shadows of the blocks sharper in the two-pass picture than in the flat one?",
      choices: ["Two-pass uses smaller patches", "In two-pass the direct light and its shadows are traced for each pixel; only the bounced light comes from the patches", "Two-pass shoots more rays per patch"],
      answer: 1,
      explain: "A patch has one radiosity for its whole area, so a shadow edge that crosses a patch is smeared over it. The two-pass method computes the light that comes straight from the lamp with shadow rays at each pixel's own point, and uses the patches only for the light bounced between surfaces, which changes slowly.",
    },
  },
  {
    id: "texture",
    title: "Texture maps",
    scene: "texture",
    text: "A texture replaces a material's diffuse colour kd at each hit: a solid 3D checker computed from the hit's position (the floor and the torus), or an image looked up by the surface's (u, v) coordinates (the ball and the wall). The geometry and the lighting stay the same.",
    controls: [{ key: "size", label: "floor checker size", kind: "select", choices: values(0.25, 0.5, 1, 2), value: 0.5, panels: [1], path: "materials.floor.texture.size" }],
    panels: [
      { label: "without textures", edit: (s) => eachMaterial(s, (m) => delete m.texture), note: "every texture removed" },
      { label: "with textures" },
    ],
    question: {
      prompt: "What does a texture map replace in the shading of a hit?",
      choices: ["the diffuse colour kd", "the surface normal", "the shape of the object", "the colour of the light"],
      answer: 0,
      explain: "A texture map gives kd per point (and ka follows it when not set). The normal is what a bump map changes; the shape and the lights are untouched, which is why shading and shadows look the same with and without.",
    },
  },
  {
    id: "bump",
    title: "Bump maps",
    scene: "bump",
    text: "A bump map tilts the shading normal by the slope of a height field (noise or an image), without moving the surface (Blinn 1978): the shading, the highlights and the reflections ripple, but silhouettes and shadows stay smooth.",
    controls: [
      {
        key: "gain",
        label: "bump strength ×",
        kind: "select",
        choices: values(0.5, 1, 2, 4),
        value: 1,
        panels: [1],
        apply: (s, v) => eachMaterial(s, (m) => m.bump && (m.bump.strength *= v)),
        note: (v) => `every bump's strength × ${v}`,
      },
    ],
    panels: [
      { label: "without bump maps", edit: (s) => eachMaterial(s, (m) => delete m.bump), note: "every bump removed" },
      { label: "with bump maps" },
    ],
    question: {
      prompt: "Look at the outline of the hammered ball with its bump map. Is it bumpy?",
      choices: ["Yes, the outline follows the bumps", "No: a bump map changes the shading normal, not the surface, so the outline stays a perfect circle"],
      answer: 1,
      explain: "Rays still hit the smooth sphere; only the normal used for shading is tilted. That is why bump maps are cheap, and why they give themselves away at silhouettes and in shadows. Moving the surface itself is displacement mapping.",
    },
  },
  {
    id: "fog",
    title: "Fog",
    scene: "fog",
    text: "Fog on every eye, reflection and transmission ray: a ray that travels a distance t keeps e^(−σ t) of what it sees and takes the rest from the fog's colour, so the row of pillars fades into grey with distance. σ is fog.density.",
    controls: [{ key: "density", label: "density σ", kind: "range", min: 0.01, max: 0.3, step: 0.01, value: 0.07, panels: [1], path: "fog.density" }],
    panels: [
      { label: "without fog", set: { "fog.density": 0 } },
      { label: (s) => `fog, density ${s.fog.density}` },
    ],
    question: {
      prompt: "A pillar twice as far away as another keeps what share of its own colour?",
      choices: ["half the near pillar's share", "the square of the near pillar's share", "the same share"],
      answer: 1,
      explain: "The share kept is e^(−σ t). At distance 2t it is e^(−2σ t) = (e^(−σ t))²: if the near pillar keeps 70 %, the far one keeps 49 %. Fog thickens exponentially with distance, not linearly.",
    },
  },
  {
    id: "etched-glass",
    title: "Semi-transparent glass with an etched image",
    scene: "etched_glass",
    text: "The pane transmits kt of the light behind it (its transmission ray, not bent: ior 1) and adds its own Phong shading, whose kd is an image texture: the etching, lit by the lamp, over what is seen through the glass. Without the texture the same pane is plain tinted glass. kt is the slider.",
    controls: [{ key: "kt", label: "the pane's kt", kind: "range", min: 0, max: 1, step: 0.05, value: 0.65, path: "materials.etched.kt" }],
    panels: [
      { label: "plain glass (no texture)", edit: (s) => delete s.materials.etched.texture, note: "materials.etched.texture removed" },
      { label: "etched glass (image texture)" },
    ],
    question: {
      prompt: "Set kt to 0. What is seen of the red ball behind the pane?",
      choices: ["nothing: no transmission ray is traced, the pane is opaque", "the ball, only dimmer", "only the ball's shadow"],
      answer: 0,
      explain: "Through the pane, the ball is only seen by the transmission ray, whose weight is kt. With kt = 0 it is not traced at all, and the pane shows only its own shading: the etched image on an opaque card.",
    },
  },
];

/** The ray tree question: the tree of one pixel of the glass ball at max_depth 3, predicted before it is shown. */
async function rayTreeQuestion(ctx) {
  const [x, y] = GLASS_PIXEL;
  const scene = await ctx.scene("whitted");
  Object.assign(scene.render, { max_depth: 3, min_weight: 0 });
  scene.sampler = { type: "jittered", spp: 4 };
  scene.film = { ...scene.film, width: SIZE[0], height: SIZE[1] };
  const tree = await api.raytree(JSON.stringify(scene), x, y, 0);
  const spawned = tree.nodes.filter((n) => n.kind === "reflection" || n.kind === "transmission");
  const n = spawned.length;
  const lo = Math.max(0, n - 2);
  const choices = [0, 1, 2, 3, 4].map((k) => lo + k);
  ctx.mark(0, x, y);
  const where = (node) => (node.hit ? node.hit.object_name : "leaves the scene");
  return {
    prompt: `Predict the ray tree of pixel (${x}, ${y}), on the glass ball (marked on the left picture), with max_depth 3 and min_weight 0: how many reflection and transmission rays does it hold (not counting the eye ray and the shadow rays)?`,
    choices: choices.map(String),
    answer: choices.indexOf(n),
    explain: `${n}. The eye ray hits the ${where(tree.nodes[0])}; ${spawned.map((r) => `a ${r.kind} ray at depth ${r.depth} ${r.hit ? `hits the ${where(r)}` : "leaves the scene"}`).join("; ")}. Depth 3 is the last generation: the rays spawned at depth 3 would be depth 4, so the tree stops there. Open the left picture in the workspace and click the pixel to see the tree drawn.`,
  };
}

/** Set `obj`'s field at a dotted path ("render.max_depth"), making the sections on the way. */
function setPath(obj, dotted, value) {
  const keys = dotted.split(".");
  let o = obj;
  for (const k of keys.slice(0, -1)) {
    if (!o[k] || typeof o[k] !== "object") o[k] = {};
    o = o[k];
  }
  o[keys[keys.length - 1]] = value;
}

/** Does control `c` change panel `i`? (No `panels`: every panel.) */
const touches = (c, i) => !c.panels || c.panels.includes(i);

/** A control's change written as a note: `render.max_depth = 3`. */
function controlNote(c, v) {
  return c.note ? c.note(v) : `${c.path} = ${JSON.stringify(v)}`;
}

/** The rays a job traced, by kind: "12,345 rays: 9,600 eye, 2,745 shadow". */
function rayWords(rays) {
  if (!rays) return "";
  const kinds = Object.entries(rays).filter(([k, n]) => k !== "total" && n > 0);
  return `${integer(rays.total)} rays${kinds.length ? `: ${kinds.map(([k, n]) => `${integer(n)} ${k}`).join(", ")}` : ""}`;
}

/** The pixel [x, y] whose samples panel `panel` draws: its own `samples` (null: none), else the lesson's. */
function samplesPixel(lesson, panel) {
  const spec = lesson.panels[panel.index];
  return spec.samples !== undefined ? spec.samples : lesson.samples;
}

/** The RMS difference of two pictures' pixels (ImageData of one size) over R, G and B, in levels of 255. */
function rmsDifference(a, b) {
  if (a.width !== b.width || a.height !== b.height) return null;
  let sum = 0;
  for (let i = 0; i < a.data.length; i += 4) for (let k = 0; k < 3; k++) sum += (a.data[i + k] - b.data[i + k]) ** 2;
  return Math.sqrt(sum / (a.width * a.height * 3));
}

/** The image of a panel (its picture, or its rays-per-pixel map): made here only, one place for every panel. */
export function panelImage(panel, kind = "picture") {
  const { width, height } = panel.scene.film;
  const alt = kind === "picture" ? `${panel.label}: rendering` : `${panel.label}: rays per pixel`;
  return h("img", { class: kind === "picture" ? "lesson-picture" : "rays-map", alt, width, height });
}

export class Lessons {
  constructor(root, { openInWorkspace }) {
    this.root = root;
    this.openInWorkspace = openInWorkspace;
    this.list = $("#lesson-list", root);
    this.stage = $("#lesson-stage", root);
    this.scenes = new Map();
    this.runs = new Map(); // lesson id -> {values, panels: [...], question}, kept while the page lives
    this.list.replaceChildren(
      ...LESSONS.map((l) =>
        h("li", {}, h("button", { type: "button", class: "lesson-button", dataset: { lesson: l.id }, onclick: () => this.run(l.id) }, l.title)),
      ),
    );
    this.stage.replaceChildren(h("p", { class: "hint" }, "Choose a comparison: its images render in a few seconds."));
  }

  async scene(name) {
    if (!this.scenes.has(name)) this.scenes.set(name, await api.scene(name));
    return clone(this.scenes.get(name));
  }

  /** The scene of panel `index`: its example, the lesson's and the panel's changes and the controls' values
   * (in that order), at lesson size; with the notes that say what changed. */
  async build(lesson, index, values) {
    const panel = lesson.panels[index];
    const s = await this.scene(panel.scene || lesson.scene);
    for (const [k, v] of Object.entries(lesson.set || {})) setPath(s, k, v);
    if (lesson.edit) lesson.edit(s);
    for (const [k, v] of Object.entries(panel.set || {})) setPath(s, k, v);
    const notes = Object.entries(panel.set || {}).map(([key, v]) => `${key} = ${JSON.stringify(v)}`);
    for (const c of lesson.controls || []) {
      if (!touches(c, index)) continue;
      if (c.apply) c.apply(s, values[c.key]);
      else setPath(s, c.path, values[c.key]);
      notes.push(controlNote(c, values[c.key]));
    }
    if (panel.edit) panel.edit(s);
    if (panel.note) notes.push(panel.note);
    const w = s.film?.width ?? 256;
    const hh = s.film?.height ?? 256;
    const k = Math.min(SIZE[0] / w, SIZE[1] / hh);
    s.film = { ...(s.film || {}), width: Math.max(1, Math.round(w * k)), height: Math.max(1, Math.round(hh * k)) };
    const label = typeof panel.label === "function" ? panel.label(s) : panel.label;
    return { scene: s, notes, label, index, lesson: lesson.id, reveal: panel.reveal, status: "new" };
  }

  async run(id) {
    const lesson = LESSONS.find((l) => l.id === id);
    for (const b of this.list.querySelectorAll("button")) b.setAttribute("aria-current", String(b.dataset.lesson === id));
    this.current = id;
    let run = this.runs.get(id);
    const fresh = !run;
    if (!run) {
      run = { values: Object.fromEntries((lesson.controls || []).map((c) => [c.key, c.value])), panels: [], answered: false };
      run.settle = debounce(() => this.rerender(lesson, run), SETTLE_MS);
      run.dirty = new Set();
      this.runs.set(id, run);
    }
    const grid = h("div", { class: "lesson-panels", dataset: { count: lesson.panels.length } });
    inspectGroup(grid, ".lesson-image img"); // a magnifier over every panel at once, and the full-size view
    const controls = this.controlsElement(lesson, run);
    const extra = h("div", { class: "lesson-extra" });
    const question = h("section", { class: "lesson-question", "aria-label": "Check yourself" });
    this.stage.replaceChildren(h("h2", { tabindex: -1 }, lesson.title), h("p", { class: "lesson-text" }, lesson.text), controls, grid, extra, question);
    this.stage.querySelector("h2").focus();
    this.stage.dataset.lesson = id;
    run.extra = extra;
    if (fresh) {
      try {
        for (let i = 0; i < lesson.panels.length; i++) run.panels.push(await this.build(lesson, i, run.values));
      } catch (err) {
        this.runs.delete(id);
        grid.replaceChildren(h("p", { class: "message", dataset: { kind: "error" } }, `Could not load the lesson's scenes: ${err.message}.`));
        return;
      }
    }
    for (const panel of run.panels) {
      panel.el = this.panelElement(lesson, run, panel);
      grid.append(panel.el.root);
      this.paint(panel);
    }
    if (lesson.coc) extra.append(run.cocText ?? (run.cocText = h("p", { class: "coc-text", role: "status" }, "Click a point of a picture for its circle of confusion.")));
    this.showQuestion(lesson, run, question);
    if (fresh) await this.start(run.panels);
  }

  /** Submit panels at once (the queue keeps their order), then follow them one by one. */
  async start(panels) {
    await Promise.all(
      panels.map(async (panel) => {
        try {
          panel.job = await api.submit(JSON.stringify(panel.scene));
          panel.status = "queued";
          if (panel.superseded) this.cancel(panel); // a control changed while it was being submitted
        } catch (err) {
          panel.status = "refused";
          panel.error = err instanceof ApiError ? err.errors : [{ path: "", message: err.message }];
        }
        this.paint(panel);
      }),
    );
    for (const panel of panels) if (panel.job && !panel.superseded) await this.follow(panel);
  }

  cancel(panel) {
    panel.following?.close();
    if (panel.job && !panel.job.finished && panel.status !== "done") api.cancel(panel.job.id).catch(() => {}); // it may have ended meanwhile
  }

  /** The lesson's controls: each change marks the panels it touches, which re-render once the changes settle. */
  controlsElement(lesson, run) {
    if (!lesson.controls?.length) return h("div", { class: "lesson-controls", hidden: true });
    return h(
      "form",
      { class: "lesson-controls", "aria-label": "What to change", onsubmit: (e) => e.preventDefault() },
      ...lesson.controls.map((c) => {
        const id = `lc-${lesson.id}-${c.key}`;
        const out = h("output", { for: id }, c.kind === "range" ? num(run.values[c.key]) : "");
        let input;
        if (c.kind === "range") {
          input = h("input", { type: "range", id, min: c.min, max: c.max, step: c.step, value: run.values[c.key], dataset: { key: c.key } });
          input.addEventListener("input", () => {
            out.textContent = num(Number(input.value));
            this.changed(lesson, run, c, Number(input.value));
          });
        } else {
          const current = JSON.stringify(run.values[c.key]);
          input = h("select", { id, dataset: { key: c.key } }, ...c.choices.map(([v, text]) => h("option", { value: JSON.stringify(v), selected: JSON.stringify(v) === current }, text)));
          input.addEventListener("change", () => this.changed(lesson, run, c, JSON.parse(input.value)));
        }
        return h("div", { class: "lesson-control" }, h("label", { for: id }, c.label), input, out);
      }),
    );
  }

  changed(lesson, run, control, value) {
    run.values[control.key] = value;
    lesson.panels.forEach((_, i) => touches(control, i) && run.dirty.add(i));
    run.settle();
  }

  /** Render again the panels the controls changed: their old jobs are cancelled, their pictures stay until the new ones come. */
  async rerender(lesson, run) {
    const indices = [...run.dirty].sort();
    run.dirty.clear();
    const fresh = [];
    for (const i of indices) {
      const old = run.panels[i];
      old.superseded = true;
      this.cancel(old);
      const panel = await this.build(lesson, i, run.values);
      panel.samples = null;
      run.panels[i] = panel;
      if (old.el) {
        panel.el = old.el;
        panel.el.panel = panel;
        panel.el.info.textContent = "";
        this.caption(panel);
        if (panel.el.samples) this.drawPixelSamples(panel, samplesPixel(lesson, panel), panel.el.samples.canvas, panel.el.samples.words);
      }
      this.paint(panel);
      fresh.push(panel);
    }
    for (const p of run.panels) if (indices.includes(p.index) || indices.includes(lesson.panels[p.index].against)) this.clearError(p);
    await this.start(fresh);
  }

  panelElement(lesson, run, panel) {
    const img = panelImage(panel);
    const state = h("div", { class: "panel-state" });
    const bar = h("progress", { max: 1, value: 0, "aria-label": `${panel.label}: progress` });
    const info = h("p", { class: "panel-info" });
    const title = h("strong", {});
    const notes = h("code", {});
    const el = { img, state, bar, info, title, notes, panel };
    const open = h("button", { type: "button", class: "small", disabled: true, onclick: () => this.openInWorkspace(el.panel.scene, el.panel.job, el.panel.label) }, "Open in workspace");
    const rays = h("button", { type: "button", class: "small", disabled: true, "aria-pressed": "false" }, "Rays / pixel");
    rays.addEventListener("click", () => {
      const on = rays.getAttribute("aria-pressed") !== "true";
      rays.setAttribute("aria-pressed", String(on));
      const job = el.panel.job;
      showImage(img, on ? api.aovUrl(job.id, "rays") : api.imageUrl(job.id, "png", job.preview));
    });
    const actions = [open, rays];
    if (lesson.stepper) {
      const step = h("button", { type: "button", class: "small", disabled: true }, "Step through the shooting");
      step.addEventListener("click", async () => {
        await this.openInWorkspace(el.panel.scene, el.panel.job, el.panel.label);
        $("#radiosity")?.scrollIntoView({ block: "start" });
      });
      el.step = step;
      actions.push(step);
    }
    let samples = null;
    if (samplesPixel(lesson, panel)) {
      const canvas = h("canvas", { class: "samples", role: "img", "aria-label": `where the ${panel.scene.sampler?.type} sampler puts the rays of one pixel` });
      const words = h("small", {}, "asking the renderer where the samples go…");
      samples = h("div", { class: "samples-box" }, canvas, words);
      el.samples = { canvas, words };
      this.drawPixelSamples(panel, samplesPixel(lesson, panel), canvas, words);
    }
    let map = null;
    if (lesson.raysMap) {
      el.map = panelImage(panel, "rays");
      map = h("div", { class: "lesson-image rays-box", title: "rays per pixel: black few, white many" }, el.map);
    }
    if (lesson.panels[panel.index].against != null) el.error = h("p", { class: "panel-error" });
    const image = h("div", { class: "lesson-image" }, img, state);
    if (lesson.coc) {
      el.overlay = h("canvas", { class: "lesson-overlay", "aria-hidden": "true" });
      image.append(el.overlay);
      img.addEventListener("click", (e) => this.circleOfConfusion(lesson, run, el.panel, e));
      img.classList.add("clickable");
    }
    el.image = image;
    el.root = h(
      "figure",
      { class: "lesson-panel", dataset: { status: panel.status, index: panel.index } },
      image,
      bar,
      h("figcaption", {}, title, notes, info, el.error),
      map,
      samples,
      h("div", { class: "panel-actions" }, ...actions),
    );
    Object.assign(el, { open, rays });
    el.panel = panel;
    panel.el = el;
    this.caption(panel);
    this.clearError(panel);
    for (const m of run.marks || []) if (m.panel === panel.index) this.drawMark(panel, m.x, m.y);
    return el;
  }

  /** The panel's label and what changed (a mystery picture's hidden until its question is answered). */
  caption(panel) {
    const el = panel.el;
    const run = this.runs.get(panel.lesson);
    const hidden = panel.reveal && !run?.answered;
    el.title.textContent = panel.reveal && !hidden ? panel.reveal : panel.label;
    el.notes.textContent = hidden ? "" : panel.notes.join(", ");
    el.notes.hidden = !el.notes.textContent;
  }

  /** A panel's error against its reference, not known (yet). */
  clearError(panel) {
    const e = panel.el?.error;
    if (!e) return;
    delete e.dataset.rms;
    delete e.dataset.pair;
    e.textContent = "RMS difference from the reference: once both pictures are done";
  }

  /** Each panel compared with its reference (`against`): the RMS difference of their final pictures, once both
   * jobs have ended (their own PNGs, fetched and decoded here: what an <img> shows may still be a pass). The
   * reference's own noise is in it too (small: it has many more rays). */
  async compare(lesson, run) {
    for (const p of run.panels) {
      const e = p.el?.error;
      const ref = run.panels[lesson.panels[p.index].against];
      if (!e || !ref || p.job?.status !== "done" || ref.job?.status !== "done") continue;
      const pair = `${p.job.image_url} ${ref.job.image_url}`;
      if (e.dataset.pair === pair) continue;
      e.dataset.pair = pair; // a later change of either panel clears it (clearError)
      let rms;
      try {
        rms = rmsDifference(await this.pixels(run, p.job.image_url), await this.pixels(run, ref.job.image_url));
      } catch (err) {
        if (e.dataset.pair === pair) e.textContent = `Could not compare with the reference: ${err.message}.`;
        continue;
      }
      if (e.dataset.pair !== pair || rms == null) continue; // superseded meanwhile
      e.dataset.rms = rms.toFixed(4);
      e.textContent = `RMS difference from the reference: ${rms.toFixed(1)} of 255`;
    }
  }

  /** The pixels (ImageData) of a job's picture at `url`, fetched with the token once per lesson run. */
  pixels(run, url) {
    run.pixels ??= new Map();
    if (!run.pixels.has(url)) {
      const decoded = blob(url)
        .then((b) => createImageBitmap(b))
        .then((bitmap) => {
          const c = document.createElement("canvas");
          c.width = bitmap.width;
          c.height = bitmap.height;
          const ctx = c.getContext("2d", { willReadFrequently: true });
          ctx.drawImage(bitmap, 0, 0);
          return ctx.getImageData(0, 0, c.width, c.height);
        });
      decoded.catch(() => run.pixels.delete(url)); // asked again next time
      run.pixels.set(url, decoded);
    }
    return run.pixels.get(url);
  }

  /** The renderer's own sample positions in pixel [x, y] of the panel's scene (POST /api/samples), drawn. */
  async drawPixelSamples(panel, [x, y], canvas, words) {
    drawSamples(canvas, null);
    try {
      panel.samples ??= await api.samples(JSON.stringify(panel.scene), x, y);
    } catch (err) {
      words.textContent = `Could not ask the server where the samples go: ${err.message}.`;
      return;
    }
    if (panel.superseded) return;
    drawSamples(canvas, panel.samples);
    words.textContent = `pixel (${panel.samples.pixel.join(", ")}): ${samplerWords(panel.samples)}`;
  }

  paint(panel) {
    const el = panel.el;
    if (!el || el.panel !== panel) return;
    el.root.dataset.status = panel.status;
    const job = panel.job;
    if (job) el.root.dataset.job = job.id;
    if (panel.status === "refused") {
      el.state.replaceChildren(h("div", { class: "refused", role: "note" }, h("strong", {}, "The server refused this scene:"), ...panel.error.map((e) => h("p", {}, e.path ? h("code", {}, e.path) : null, e.path ? ": " : null, e.message))));
      el.img.hidden = true;
      el.bar.hidden = true;
      return;
    }
    el.img.hidden = false;
    const solving = job?.progress?.phase === "radiosity" && job.progress.solve; // the radiosity solve comes first
    el.bar.value = solving ? job.progress.solve.fraction : job?.progress?.fraction ?? 0;
    if (job && job.image_url && el.rays.getAttribute("aria-pressed") !== "true") {
      const url = job.image_url;
      showImage(el.img, url).then((ok) => ok && el.img.dataset.src === url && (el.img.dataset.shown = url)); // fetched with the token (once per pass)
      el.img.alt = panel.label;
    }
    const done = panel.status === "done";
    for (const b of [el.open, el.rays, el.step]) if (b) b.disabled = !done;
    if (!done) el.rays.setAttribute("aria-pressed", "false");
    if (done) {
      el.state.replaceChildren();
      const lesson = LESSONS.find((l) => l.id === panel.lesson);
      if (job.status === "done" && lesson.panels.some((p) => p.against != null)) this.compare(lesson, this.runs.get(panel.lesson)); // its job has ended
      el.info.textContent = `${rayWords(job.rays)} · ${seconds(job.elapsed)}`;
      el.root.dataset.image = job.image_url;
      el.bar.hidden = true;
      if (el.map) showImage(el.map, api.aovUrl(job.id, "rays")).then((ok) => ok && (el.map.alt = `${panel.label}: rays per pixel`));
    } else if (job?.finished) {
      el.state.replaceChildren(h("div", { class: "refused" }, `The job ${panel.status}: ${job.error || ""}`));
    } else {
      el.bar.hidden = false;
      el.state.replaceChildren(h("span", { class: "spinner" }, panel.status === "new" ? "submitting…" : panel.status === "queued" ? queuedShort(job) : solving ? "solving radiosity…" : "rendering…"));
    }
  }

  /** Follow one panel's job by its event stream until it ends (or a control supersedes it). */
  follow(panel) {
    panel.following = followJob(panel.job.id, {
      onProgress: (p) => {
        panel.status = p.status;
        panel.job.finished = p.phase === "finished"; // the last progress event says so just before `end`
        panel.job.progress = { ...panel.job.progress, ...p };
        this.paint(panel);
      },
      onPreview: (p) => {
        panel.job.image_url = p.url;
        this.paint(panel);
      },
      onEnd: (job) => {
        panel.job = job;
        panel.status = job.status;
        this.paint(panel);
      },
      onLost: () => {
        panel.status = "failed";
        panel.job = { ...panel.job, finished: true, error: "lost the connection to the server" }; // given up here
        this.paint(panel);
      },
    });
    return panel.following.done;
  }

  // -- the question ----------------------------------------------------------------------------------

  async showQuestion(lesson, run, box) {
    if (!lesson.question) return;
    box.replaceChildren(h("h3", {}, "Check yourself"), h("p", { class: "hint" }, "Preparing the question…"));
    if (!run.question) {
      try {
        run.question = lesson.question.make ? await lesson.question.make(this.context(lesson, run)) : lesson.question;
      } catch (err) {
        box.replaceChildren(h("h3", {}, "Check yourself"), h("p", { class: "message", dataset: { kind: "error" } }, `Could not prepare the question: ${err.message}.`));
        return;
      }
    }
    const q = run.question;
    box.question = q; // the page's tests read the answer here
    const feedback = h("div", { class: "feedback", role: "status", "aria-live": "polite" });
    const choices = q.choices.map((text, i) =>
      h("button", { type: "button", class: "choice", dataset: { choice: i }, onclick: () => this.answer(lesson, run, i, choices, feedback) }, text),
    );
    box.replaceChildren(h("h3", {}, "Check yourself"), h("p", { class: "question" }, q.prompt), h("div", { class: "choices", role: "group", "aria-label": "answers" }, ...choices), feedback);
    if (run.chosen != null) this.answer(lesson, run, run.chosen, choices, feedback);
  }

  answer(lesson, run, i, buttons, feedback) {
    const q = run.question;
    const right = i === q.answer;
    run.chosen = i;
    buttons.forEach((b, k) => {
      b.setAttribute("aria-pressed", String(k === i));
      b.dataset.verdict = k === i ? (right ? "right" : "wrong") : "";
    });
    feedback.dataset.verdict = right ? "right" : "wrong";
    feedback.replaceChildren(
      right ? h("p", {}, h("strong", {}, "Right. "), q.explain) : h("p", {}, h("strong", {}, "Not quite. "), "Look at the pictures again (change the controls if it helps) and try another answer."),
    );
    if (right && !run.answered) {
      run.answered = true;
      for (const p of run.panels) if (p.reveal && p.el) this.caption(p);
    }
  }

  /** What a question's `make` may use: the example scenes, and marks on the panels. */
  context(lesson, run) {
    return {
      scene: (name) => this.scene(name),
      panel: (i) => run.panels[i],
      mark: (i, x, y) => {
        run.marks = [...(run.marks || []), { panel: i, x, y }];
        const p = run.panels[i];
        if (p?.el) this.drawMark(p, x, y);
      },
    };
  }

  /** A marker on pixel (x, y) of a panel's picture. */
  drawMark(panel, x, y) {
    const { width, height } = panel.scene.film;
    const mark = h("span", { class: "lesson-mark", title: `pixel (${x}, ${y})`, dataset: { x, y } });
    mark.style.left = `${((x + 0.5) / width) * 100}%`;
    mark.style.top = `${((y + 0.5) / height) * 100}%`;
    panel.el.image.append(mark);
  }

  // -- depth of field: the circle of confusion of a clicked point -----------------------------------

  /** The pixel under a click on a panel's picture (object-fit: contain), or null. */
  pixelAt(panel, e) {
    const { width, height } = panel.scene.film;
    const r = panel.el.img.getBoundingClientRect();
    const k = Math.min(r.width / width, r.height / height);
    const x = Math.floor((e.clientX - r.left - (r.width - width * k) / 2) / k);
    const y = Math.floor((e.clientY - r.top - (r.height - height * k) / 2) / k);
    return x >= 0 && y >= 0 && x < width && y < height ? [x, y] : null;
  }

  async circleOfConfusion(lesson, run, panel, e) {
    const at = this.pixelAt(panel, e);
    if (!at) return;
    const [x, y] = at;
    const lens = run.panels.find((p) => p.scene.camera.lens_radius > 0) || run.panels[run.panels.length - 1];
    const pinhole = clone(lens.scene);
    pinhole.camera.lens_radius = 0;
    delete pinhole.camera.focus_distance;
    pinhole.sampler = { type: "center" };
    run.cocText.textContent = `Tracing pixel (${x}, ${y})…`;
    let tree;
    try {
      tree = await api.raytree(JSON.stringify(pinhole), x, y, 0);
    } catch (err) {
      run.cocText.textContent = `Could not trace that pixel: ${err.message}.`;
      return;
    }
    const eye = tree.nodes[0];
    if (!eye?.hit) {
      run.cocText.textContent = `Pixel (${x}, ${y}) sees the background: it has no depth, and no circle of confusion.`;
      run.coc = null;
      for (const p of run.panels) this.drawCoc(p, null);
      return;
    }
    const c = lens.scene.camera;
    const forward = normalize(sub(c.lookat, c.lookfrom));
    const z = eye.t * dot(eye.direction, forward); // the hit's depth along the view direction
    const F = c.focus_distance ?? length(sub(c.lookat, c.lookfrom));
    const hTan = Math.tan(((c.vfov ?? 40) * Math.PI) / 360);
    // the lens's disk, seen from the point through the focal point: radius A |1 - F / z| on the focal plane,
    // whose height 2 F tan(vfov / 2) spans the film's rows
    const diameter = (2 * (c.lens_radius || 0) * Math.abs(1 - F / z) * lens.scene.film.height) / (2 * F * hTan);
    run.coc = { x, y, diameter };
    for (const p of run.panels) this.drawCoc(p, p === lens ? run.coc : { x, y, diameter: 0 });
    run.cocText.dataset.diameter = diameter.toFixed(2);
    run.cocText.textContent = `Pixel (${x}, ${y}) sees the ${eye.hit.object_name} at depth ${num(z)} (along the view); the lens focuses at ${num(F)}. With lens radius ${num(c.lens_radius || 0)} a point there spreads into a disk ${num(diameter)} pixels across on the lens picture (diameter = 2·r·|1 − F/z|·height / (2·F·tan(vfov/2))).`;
  }

  /** Draw a circle of confusion (`coc`: {x, y, diameter} in film pixels; null: none) over a panel's picture. */
  drawCoc(panel, coc) {
    const canvas = panel.el?.overlay;
    if (!canvas) return;
    const box = panel.el.image.getBoundingClientRect();
    const { width, height } = panel.scene.film;
    const dpr = window.devicePixelRatio || 1;
    canvas.width = Math.round(box.width * dpr);
    canvas.height = Math.round(box.height * dpr);
    const ctx = canvas.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, box.width, box.height);
    canvas.dataset.diameter = coc ? coc.diameter.toFixed(2) : "";
    if (!coc) return;
    const k = Math.min(box.width / width, box.height / height);
    const cx = (box.width - width * k) / 2 + (coc.x + 0.5) * k;
    const cy = (box.height - height * k) / 2 + (coc.y + 0.5) * k;
    ctx.strokeStyle = "#ff7a00";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.arc(cx, cy, Math.max((coc.diameter / 2) * k, 0.5), 0, 2 * Math.PI);
    ctx.stroke();
    ctx.beginPath();
    ctx.moveTo(cx - 5, cy);
    ctx.lineTo(cx + 5, cy);
    ctx.moveTo(cx, cy - 5);
    ctx.lineTo(cx, cy + 5);
    ctx.stroke();
  }
}

/** A lesson panel's queued job: its place in line (from the server). */
function queuedShort(job) {
  const q = job?.progress?.queue || job?.queue;
  if (!q) return "queued…";
  const wait = q.expected_wait != null && q.expected_wait >= 1 ? `, ~${Math.round(q.expected_wait)} s` : "";
  return q.ahead === 0 ? `queued: next${wait}…` : `queued: #${q.position}${wait}…`;
}
