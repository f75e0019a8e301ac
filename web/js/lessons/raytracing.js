// The lessons on Whitted's ray tracing: the ray tree and where it is cut, the Phong terms, bounces.
import { api } from "../api.js";
import { eachMaterial, reference, values } from "./helpers.js";

const GLASS_PIXEL = [110, 70]; // on the glass ball of `whitted` at 160 x 120 (the lessons' size)
const QUESTION_DEPTH = 3; // the ray tree question's max_depth, where the left picture's slider starts
// "read the code": the Whitted integrator in lecture size (tracer/integrators/whitted_simple.py), as docs/renderer.md presents it
const WHITTED_CODE = ["read the code: Whitted in lecture size", "/reference/renderer.md#whitted-in-lecture-size"];

export const RAY_TRACING = [
  {
    id: "raytree-stop",
    title: "The ray tree, and when to stop",
    scene: "whitted",
    set: { "sampler.type": "jittered", "sampler.spp": 4 },
    text: "Each eye ray that hits a mirror or glass spawns a reflection ray and a transmission ray, and those spawn their own: a ray tree. A branch ends where its ray leaves the scene, or where it is cut: at max_depth, or where its contribution to the pixel, the product of the K's (kr, kt) along the way, falls below min_weight. Cutting by depth stops every branch at the same generation, bright or faint; cutting by weight stops faint branches early and lets the bright ones (a mirror seen in a mirror) go deep. Compare the pictures and what each cost in rays.",
    more: [
      reference("the ray tree", "the-ray-tree"),
      reference("why a ray ends", "why-a-ray-ends"),
      reference("reflection and transmission rays", "reflection-and-transmission-rays"),
      WHITTED_CODE,
    ],
    controls: [
      {
        key: "depth",
        label: "max_depth (left)",
        kind: "range",
        min: 1,
        max: 10,
        step: 1,
        value: QUESTION_DEPTH,
        panels: [0],
        path: "render.max_depth",
      },
      {
        key: "weight",
        label: "min_weight (right)",
        kind: "select",
        choices: values(0.001, 0.05, 0.2, 0.5, 0.9),
        value: 0.2,
        panels: [1],
        path: "render.min_weight",
      },
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
    text: "The local shading of a hit: I = ka·Ia + f_att·Ip·(kd cos θ + ks cosⁿ φ), with θ between the normal and the light, φ between the mirror direction of the light and the eye, and f_att = 1 / (c1 + c2 d + c3 d²) dimming the point light with its distance d. The three pictures add the terms one at a time: the left one has only the ambient term, on the floor as on the ball (no surface takes the light in: no shading, no shadow). The sliders change the ball's coefficients in the pictures that have their term (kd from the middle one on, ks and n on the right), and the light's attenuation, which shows best on the floor.",
    more: [
      reference("the local term", "the-local-term"),
      reference("materials", "materials"),
      reference("the point light's attenuation", "point-light"),
    ],
    controls: [
      {
        key: "ka",
        label: "ka (ambient)",
        kind: "range",
        min: 0,
        max: 1,
        step: 0.05,
        value: 0.3,
        apply: (s, v) => (s.materials.ball.ka = v),
        note: (v) => `ka = ${v}`,
      },
      {
        key: "kd",
        label: "kd (diffuse)",
        kind: "range",
        min: 0,
        max: 1,
        step: 0.05,
        value: 0.7,
        panels: [1, 2],
        apply: (s, v) => (s.materials.ball.kd = [0.3 * v, 0.5 * v, v]),
        note: (v) => `kd = ${v} × blue`,
      },
      {
        key: "ks",
        label: "ks (specular)",
        kind: "range",
        min: 0,
        max: 1,
        step: 0.05,
        value: 0.5,
        panels: [2],
        apply: (s, v) => (s.materials.ball.ks = v),
        note: (v) => `ks = ${v}`,
      },
      {
        key: "n",
        label: "n (shininess)",
        kind: "select",
        choices: values(2, 8, 32, 64, 256, 1024),
        value: 64,
        panels: [2],
        apply: (s, v) => (s.materials.ball.shininess = v),
        note: (v) => `n = ${v}`,
      },
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
        panels: [1, 2], // the light's fall-off: nothing to change where no light is taken in
        apply: (s, v) => (s.lights[0].attenuation = v),
        note: (v) => `attenuation = ${JSON.stringify(v)}`,
      },
    ],
    panels: [
      // every surface (the floor too: no light on it, no shadow), each keeping its ka (by default its kd)
      {
        label: "ambient only: ka·Ia",
        edit: (s) => eachMaterial(s, (m) => Object.assign(m, { ka: m.ka ?? m.kd, kd: 0, ks: 0 })),
        note: "kd = ks = 0 everywhere (each ka kept)",
      },
      {
        label: "+ diffuse: f_att·Ip·kd cos θ",
        edit: (s) => Object.assign(s.materials.ball, { ks: 0 }),
        note: "ks = 0",
      },
      { label: "+ specular: f_att·Ip·ks cosⁿ φ (Phong)" },
    ],
    question: {
      prompt: "Raise n, the shininess. What does the highlight on the right-hand picture do?",
      choices: [
        "It grows larger and dimmer",
        "It shrinks to a smaller, sharper spot",
        "It moves across the ball",
        "It takes the ball's colour",
      ],
      answer: 1,
      explain:
        "cosⁿ φ falls off faster the larger n is, so only directions very close to the mirror direction of the light stay bright: a small, sharp highlight (a polished surface). A small n gives a broad, soft one. The highlight keeps the light's colour, since ks is white here.",
    },
  },
  {
    id: "bounces",
    title: "Ray casting vs 2 vs 3 bounces",
    scene: "whitted",
    set: { "sampler.type": "jittered", "sampler.spp": 4 },
    text: "max_depth counts bounces of light on the way to the eye. With 1 (ray casting) the mirror and the glass show only their own Phong shading; with 2 the mirror reflects the scene but the glass ball is dark inside, because the transmitted ray is cut before it can leave the ball; with 3 the refracted floor appears through the glass.",
    more: [
      reference("integrators and depth", "integrators-and-depth"),
      reference("reflection and transmission rays", "reflection-and-transmission-rays"),
    ],
    controls: [
      {
        key: "kr",
        label: "the mirror ball's kr (no effect on ray casting)",
        kind: "range",
        min: 0,
        max: 1,
        step: 0.05,
        value: 0.85,
        panels: [1, 2],
        path: "materials.mirror.kr",
      },
    ],
    panels: [
      { label: "ray casting (1 bounce)", set: { "render.max_depth": 1 } },
      { label: "ray tracing, 2 bounces", set: { "render.max_depth": 2 } },
      { label: "ray tracing, 3 bounces", set: { "render.max_depth": 3 } },
    ],
    question: {
      prompt: "With 2 bounces, why is the glass ball dark inside?",
      choices: [
        "The glass absorbs the light",
        "The transmitted ray enters the ball at depth 2 and is cut before it can leave it",
        "Its shadow rays are blocked by the glass",
        "Glass has no diffuse colour, so nothing is seen through it",
      ],
      answer: 1,
      explain:
        "The eye ray (depth 1) hits the ball and spawns a transmission ray (depth 2), which meets the ball's far side from inside. Leaving the ball needs one more transmission ray, at depth 3: with max_depth 2 it is not traced, so that branch brings back nothing but the local shading (black: kd = 0).",
    },
  },
];

/** The ray tree question: the tree of one pixel of the glass ball at max_depth QUESTION_DEPTH (the left picture's
 * first depth), predicted before it is shown. */
async function rayTreeQuestion(ctx) {
  const [x, y] = GLASS_PIXEL;
  const scene = await ctx.scene("whitted");
  Object.assign(scene.render, { max_depth: QUESTION_DEPTH, min_weight: 0 });
  scene.sampler = { type: "jittered", spp: 4 };
  scene.film = { ...scene.film, width: ctx.size[0], height: ctx.size[1] };
  const tree = await api.raytree(JSON.stringify(scene), x, y, 0);
  const spawned = tree.nodes.filter((n) => n.kind === "reflection" || n.kind === "transmission");
  const n = spawned.length;
  const lo = Math.max(0, n - 2);
  const choices = [0, 1, 2, 3, 4].map((k) => lo + k);
  ctx.mark(0, x, y);
  const where = (node) => (node.hit ? node.hit.object_name : "leaves the scene");
  return {
    prompt: `Predict the ray tree of pixel (${x}, ${y}), on the glass ball (marked on the left picture), with max_depth ${QUESTION_DEPTH} and min_weight 0: how many reflection and transmission rays does it hold (not counting the eye ray and the shadow rays)?`,
    choices: choices.map(String),
    answer: choices.indexOf(n),
    explain: `${n}. The eye ray hits the ${where(tree.nodes[0])}; ${spawned.map((r) => `a ${r.kind} ray at depth ${r.depth} ${r.hit ? `hits the ${where(r)}` : "leaves the scene"}`).join("; ")}. Depth ${QUESTION_DEPTH} is the last generation: the rays spawned at depth ${QUESTION_DEPTH} would be depth ${QUESTION_DEPTH + 1}, so the tree stops there. The left picture is cut at depth ${QUESTION_DEPTH} when the lesson opens (set its slider back to ${QUESTION_DEPTH} if you moved it): open it in the workspace and click the marked pixel to see this tree drawn.`,
  };
}
