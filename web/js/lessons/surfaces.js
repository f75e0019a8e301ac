// The lessons on what a surface (and the air) adds: texture maps, bump maps, fog, etched glass.
import { eachMaterial, reference, values } from "./helpers.js";

export const SURFACES = [
  {
    id: "texture",
    title: "Texture maps",
    scene: "texture",
    text: "A texture replaces a material's diffuse colour kd at each hit: a solid 3D checker computed from the hit's position (the floor and the torus), or an image looked up by the surface's (u, v) coordinates (the ball and the wall). The geometry and the lighting stay the same.",
    more: [reference("textures and bump maps", "textures-and-bump-maps")],
    controls: [
      {
        key: "size",
        label: "floor checker size",
        kind: "select",
        choices: values(0.25, 0.5, 1, 2),
        value: 0.5,
        panels: [1],
        path: "materials.floor.texture.size",
      },
    ],
    panels: [
      {
        label: "without textures",
        edit: (s) => eachMaterial(s, (m) => delete m.texture),
        note: "every texture removed",
      },
      { label: "with textures" },
    ],
    question: {
      prompt: "What does a texture map replace in the shading of a hit?",
      choices: ["the diffuse colour kd", "the surface normal", "the shape of the object", "the colour of the light"],
      answer: 0,
      explain:
        "A texture map gives kd per point (and ka follows it when not set). The normal is what a bump map changes; the shape and the lights are untouched, which is why shading and shadows look the same with and without.",
    },
  },
  {
    id: "bump",
    title: "Bump maps",
    scene: "bump",
    text: "A bump map tilts the shading normal by the slope of a height field (noise or an image), without moving the surface (Blinn 1978): the shading, the highlights and the reflections ripple, but silhouettes and shadows stay smooth.",
    more: [reference("textures and bump maps", "textures-and-bump-maps")],
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
      choices: [
        "Yes, the outline follows the bumps",
        "No: a bump map changes the shading normal, not the surface, so the outline stays a perfect circle",
      ],
      answer: 1,
      explain:
        "Rays still hit the smooth sphere; only the normal used for shading is tilted. That is why bump maps are cheap, and why they give themselves away at silhouettes and in shadows. Moving the surface itself is displacement mapping.",
    },
  },
  {
    id: "fog",
    title: "Fog",
    scene: "fog",
    text: "Fog on every eye, reflection and transmission ray: a ray that travels a distance t keeps e^(−σ t) of what it sees and takes the rest from the fog's colour, so the row of pillars fades into grey with distance. σ is fog.density.",
    more: [reference("fog along a ray", "fog-along-a-ray"), reference("the fog fields", "fog")],
    controls: [
      {
        key: "density",
        label: "density σ",
        kind: "range",
        min: 0.01,
        max: 0.3,
        step: 0.01,
        value: 0.07,
        panels: [1],
        path: "fog.density",
      },
    ],
    panels: [{ label: "without fog", set: { "fog.density": 0 } }, { label: (s) => `fog, density ${s.fog.density}` }],
    question: {
      prompt: "A pillar twice as far away as another keeps what share of its own colour?",
      choices: ["half the near pillar's share", "the square of the near pillar's share", "the same share"],
      answer: 1,
      explain:
        "The share kept is e^(−σ t). At distance 2t it is e^(−2σ t) = (e^(−σ t))²: if the near pillar keeps 70 %, the far one keeps 49 %. Fog thickens exponentially with distance, not linearly.",
    },
  },
  {
    id: "etched-glass",
    title: "Semi-transparent glass with an etched image",
    scene: "etched_glass",
    text: "The pane transmits kt of the light behind it (its transmission ray, not bent: ior 1) and adds its own Phong shading, whose kd is an image texture: the etching, lit by the lamp, over what is seen through the glass. Without the texture the same pane is plain tinted glass. kt is the slider.",
    more: [reference("materials: kt and ior", "materials"), reference("textures", "textures-and-bump-maps")],
    controls: [
      {
        key: "kt",
        label: "the pane's kt",
        kind: "range",
        min: 0,
        max: 1,
        step: 0.05,
        value: 0.65,
        path: "materials.etched.kt",
      },
    ],
    panels: [
      {
        label: "plain glass (no texture)",
        edit: (s) => delete s.materials.etched.texture,
        note: "materials.etched.texture removed",
      },
      { label: "etched glass (image texture)" },
    ],
    question: {
      prompt: "Set kt to 0. What is seen of the red ball behind the pane?",
      choices: [
        "nothing: no transmission ray is traced, the pane is opaque",
        "the ball, only dimmer",
        "only the ball's shadow",
      ],
      answer: 0,
      explain:
        "Through the pane, the ball is only seen by the transmission ray, whose weight is kt. With kt = 0 it is not traced at all, and the pane shows only its own shading: the etched image on an opaque card.",
    },
  },
];
