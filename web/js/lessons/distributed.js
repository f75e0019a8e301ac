// The lessons on distributed ray tracing: glossy reflection, soft shadows, depth of field.
import { eachMaterial, reference, values } from "./helpers.js";

/** The scene's square ceiling light (a quad) as a point light at its centre, a little below it, as bright
 * straight down: a small area light acts as a point light of intensity radiance · area · cos θ
 * (docs/scene-format.md), so the two light the floor under them alike and only the shadows' edges differ. */
function pointLight(s) {
  const q = s.lights.find((l) => l.type === "quad");
  const centre = q.corner.map((c, k) => c + (q.edge1[k] + q.edge2[k]) / 2);
  const cross = [
    q.edge1[1] * q.edge2[2] - q.edge1[2] * q.edge2[1],
    q.edge1[2] * q.edge2[0] - q.edge1[0] * q.edge2[2],
    q.edge1[0] * q.edge2[1] - q.edge1[1] * q.edge2[0],
  ];
  const area = Math.hypot(...cross);
  const down = cross.map((c) => (0.01 * c) / area); // 1 cm along the side it emits on
  const radiance = Array.isArray(q.radiance) ? q.radiance : [q.radiance, q.radiance, q.radiance];
  s.lights = s.lights.map((l) =>
    l === q
      ? { type: "point", position: centre.map((c, k) => c + down[k]), intensity: radiance.map((r) => r * area) }
      : l,
  );
}

export const DISTRIBUTED = [
  {
    id: "glossy",
    title: "Glossy reflection: a cone of rays",
    scene: "glossy",
    set: { "sampler.spp": 16 },
    text: "A perfect mirror sends one reflection ray. A glossy surface sends reflection rays in a cone around the mirror direction, narrower the larger the material's gloss m (a direction at angle α from the mirror direction is drawn in proportion to cos^m α, like the Phong exponent n of a highlight): averaged over the pixel's rays, the reflections of the other objects blur. The left ball's m is the slider; the others keep theirs (300, 40, and frosted glass 150). Fewer rays per pixel: a noisier blur.",
    more: [
      reference("materials and their gloss", "materials"),
      reference("reflection and transmission rays", "reflection-and-transmission-rays"),
    ],
    controls: [
      {
        key: "m",
        label: "gloss m (left ball)",
        kind: "select",
        choices: values(10, 40, 150, 600, 3000),
        value: 40,
        panels: [1],
        path: "materials.mirror.gloss",
      },
      {
        key: "spp",
        label: "rays per pixel",
        kind: "select",
        choices: values(4, 16, 64),
        value: 16,
        path: "sampler.spp",
      },
    ],
    panels: [
      {
        label: "perfect mirrors: one reflection ray",
        edit: (s) => eachMaterial(s, (m) => delete m.gloss),
        note: "every gloss removed",
      },
      { label: (s) => `glossy: a cone of rays, left ball m = ${s.materials.mirror.gloss}` },
    ],
    question: {
      prompt:
        "A glossy ball shows a fuzzy highlight of the lamp. Does that highlight light up the floor next to the ball?",
      choices: [
        "Yes, the floor gets brighter under it",
        "No: a highlight is only the ball's local term, and the floor sends no rays towards the ball to pick it up",
      ],
      answer: 1,
      explain:
        "The highlight ks cosⁿ φ is computed at the ball for the eye's direction; it is not light that leaves the ball towards other objects. The diffuse floor gathers light only through its shadow rays to the lamp. Only a reflection ray (from a mirror, or a glossy cone sampled stochastically) sees other objects, which is why glossy reflections of the orange block blur while the lamp's light on the floor does not change.",
    },
  },
  {
    id: "shadows",
    title: "Hard vs soft shadows",
    scene: "cornell_whitted_area",
    set: { "sampler.type": "jittered", "sampler.spp": 4 },
    text: "The same box in the three pictures. On the left, the ceiling's square light is a point light at its centre, as bright straight down: it casts hard shadows, as a point is lit or not. An area light is sampled with light_samples shadow rays to random points of the light per shading point: the fraction that reaches the light makes the penumbra. Fewer rays, more noise; more rays, less noise (and more shadow rays to pay for). The penumbra is widest where the shadow is far from the object that casts it.",
    more: [reference("area lights", "area-lights"), reference("shadow rays", "shadow-rays")],
    controls: [
      {
        key: "light",
        label: "shadow rays per point (right)",
        kind: "range",
        min: 1,
        max: 32,
        step: 1,
        value: 16,
        panels: [2],
        path: "render.light_samples",
      },
    ],
    panels: [
      { label: "point light: hard shadows", edit: pointLight, note: "the square light → a point light at its centre" },
      { label: "area light, 1 shadow ray", set: { "render.light_samples": 1 } },
      { label: (s) => `area light, ${s.render.light_samples} shadow rays` },
    ],
    question: {
      prompt: "Where is the penumbra of a block's shadow widest?",
      choices: [
        "right where the block stands on the floor",
        "far from the block, at the shadow's far edge",
        "it has the same width everywhere",
      ],
      answer: 1,
      explain:
        "By similar triangles: the penumbra's width is the light's size times (distance from the occluding edge to the floor) / (distance from the light to that edge). Where the block touches the floor that distance is 0 and the shadow is sharp; it widens with distance from the block.",
    },
  },
  {
    id: "dof",
    title: "Pinhole vs depth of field",
    scene: "depth_of_field",
    set: { "sampler.spp": 16 },
    coc: true,
    text: "A pinhole camera sends every eye ray through one point: everything is sharp. A thin lens starts eye rays at random points of the lens, all through the point where the pinhole ray meets the focal plane: objects on that plane stay sharp, the others blur in proportion to their distance from it. Click a point of either picture: its circle of confusion (the disk a point at that depth spreads into) is drawn on the lens picture, from the thin-lens formula.",
    more: [
      reference("camera rays through a thin lens", "camera-rays"),
      reference("the camera's lens fields", "camera"),
    ],
    controls: [
      {
        key: "radius",
        label: "lens radius",
        kind: "range",
        min: 0,
        max: 0.4,
        step: 0.01,
        value: 0.15,
        panels: [1],
        path: "camera.lens_radius",
      },
      {
        key: "focus",
        label: "focus distance",
        kind: "range",
        min: 3,
        max: 13,
        step: 0.1,
        value: 7.3,
        panels: [1],
        path: "camera.focus_distance",
      },
    ],
    panels: [
      { label: "pinhole", set: { "camera.lens_radius": 0 } },
      { label: (s) => `thin lens, radius ${s.camera.lens_radius}, focused at ${s.camera.focus_distance ?? "lookat"}` },
    ],
    question: {
      prompt:
        "The lens focuses 7.3 units in front of it, on the green ball. Which ball has the largest circle of confusion?",
      choices: [
        "the near red ball (about 4 units away)",
        "the green ball",
        "the far blue ball (about 11.7 units away)",
      ],
      answer: 0,
      explain:
        "The circle's diameter on the film grows with |1 − F/z| for a point at depth z and focus distance F: 0.84 for the red ball (z ≈ 4.0), 0.01 for the green one, 0.37 for the blue one (z ≈ 11.7). In front of the focal plane the blur grows fast, behind it slowly (it tends to the lens's size as z goes to infinity).",
    },
  },
];
