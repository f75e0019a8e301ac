// The lessons on light bounced between surfaces: Whitted vs path tracing vs radiosity, Monte Carlo noise,
// radiosity's displays.
import { reference, values } from "./helpers.js";

/** A reference panel of the noise lesson: many rays, and another seed than the panels it is compared with (a
 * low-discrepancy panel's points are the first ones of the same seed's longer sequence). */
const REFERENCE = { "sampler.type": "lowdiscrepancy", "sampler.spp": 256, "render.seed": 1 };

export const INDIRECT = [
  {
    id: "integrators",
    title: "Diffuse interreflection: Whitted + ambient vs path tracing vs radiosity",
    scene: "cornell_path",
    set: { "sampler.spp": 16 },
    text: "The same Cornell box and ceiling light. Whitted's ray tree follows only mirror and refraction rays: soft shadows from the area light, but light does not bounce between walls; its ambient term (ka·Ia, the slider) fakes the missing light with one constant. The path tracer samples diffuse bounces too: red and green bleed onto the white blocks and the ceiling is lit. Radiosity solves diffuse interreflection between the diffuse surfaces first (patches and form factors), then traces the ray tree for direct light and mirrors.",
    more: [
      reference("integrators and depth", "integrators-and-depth"),
      reference("the ambient term", "the-local-term"),
    ],
    controls: [
      {
        key: "ambient",
        label: "Whitted's ambient Ia",
        kind: "range",
        min: 0,
        max: 0.5,
        step: 0.05,
        value: 0,
        panels: [0],
        path: "ambient",
      },
    ],
    panels: [
      { label: (s) => `Whitted ray tracing, ambient ${s.ambient}`, set: { "render.integrator": "whitted" } },
      { label: "path tracing", set: { "render.integrator": "path" } },
      { label: "radiosity", set: { "render.integrator": "radiosity" } },
    ],
    question: {
      prompt: "Why is the ceiling dark in the Whitted picture, but lit in the other two?",
      choices: [
        "The ceiling's material is black",
        "The light faces down: the ceiling gets only light bounced off the walls, which Whitted's tree does not follow",
        "Whitted's picture has too few rays per pixel",
      ],
      answer: 1,
      explain:
        "The ceiling light emits downwards, so no shadow ray from the ceiling reaches its bright side. All the ceiling's light comes from other surfaces: diffuse interreflection. Path tracing follows it with random diffuse bounces, radiosity with form factors between patches; Whitted's ambient term only adds the same constant everywhere.",
    },
  },
  {
    id: "noise",
    title: "Noise: random vs jittered vs low-discrepancy (quasi-Monte Carlo)",
    samples: [44, 37], // the pixel whose samples are drawn (at 160 x 120 and 120 x 120)
    text: "A pixel's colour is an average (over its area, and over the lens, the shutter and a path's bounces) estimated from a few rays: the estimate is off by a random error, the noise. How the rays' points are spread changes that error, not the picture they converge to. Random: independent points, which clump and leave gaps. Jittered: one random point in each cell of a √n × √n grid (stratified). Low-discrepancy (quasi-Monte Carlo: Monte Carlo with points placed evenly on purpose instead of independently): the successive points of a Sobol sequence, a fixed sequence built so that its first points already spread evenly, shuffled at random for each pixel. Its first 4, 8, 16, … points (a power of 2) lie one in each box of any grid of that many equal boxes: at 16 rays, one in each of the 4 × 4 cells, and also one in each of 16 thin columns and 16 thin rows (such a set is called a (0,k,2)-net). The sampler chooses only where a ray crosses the pixel (and the lens, and the shutter time); a path's bounce directions and its points on the light come from the path's own points, the same for all three. Under each picture: one pixel's rays, and how far the picture is from the row's reference (256 rays per pixel, another seed; its own small noise counts too), as the RMS difference: the square root of the mean squared difference of the pixels' levels, 0 to 255. Top: ray tracing with a point light. Bottom: the path-traced Cornell box.",
    more: [
      reference("the samplers, low-discrepancy among them", "sampler"),
      reference("random numbers", "random-numbers"),
    ],
    controls: [
      {
        key: "spp",
        label: "rays per pixel (all but the references)",
        kind: "select",
        choices: values(4, 16, 64),
        value: 16,
        panels: [0, 1, 2, 4, 5, 6],
        path: "sampler.spp",
      },
    ],
    panels: [
      {
        label: (s) => `random, ${s.sampler.spp} rays`,
        scene: "antialias_jittered",
        set: { "sampler.type": "random" },
        against: 3,
      },
      {
        label: (s) =>
          `jittered, ${s.sampler.spp} rays (${Math.sqrt(s.sampler.spp)} × ${Math.sqrt(s.sampler.spp)} cells)`,
        scene: "antialias_jittered",
        set: { "sampler.type": "jittered" },
        against: 3,
      },
      {
        label: (s) => `low-discrepancy, ${s.sampler.spp} rays`,
        scene: "antialias_jittered",
        set: { "sampler.type": "lowdiscrepancy" },
        against: 3,
      },
      { label: "reference: low-discrepancy, 256 rays", scene: "antialias_jittered", set: REFERENCE, samples: null },
      {
        label: (s) => `path traced, random, ${s.sampler.spp} rays`,
        scene: "cornell_path",
        set: { "sampler.type": "random" },
        against: 7,
      },
      {
        label: (s) =>
          `path traced, jittered, ${s.sampler.spp} rays (${Math.sqrt(s.sampler.spp)} × ${Math.sqrt(s.sampler.spp)} cells)`,
        scene: "cornell_path",
        set: { "sampler.type": "jittered" },
        against: 7,
      },
      {
        label: (s) => `path traced, low-discrepancy, ${s.sampler.spp} rays`,
        scene: "cornell_path",
        set: { "sampler.type": "lowdiscrepancy" },
        against: 7,
      },
      {
        label: "path traced reference: low-discrepancy, 256 rays",
        scene: "cornell_path",
        set: REFERENCE,
        samples: null,
      },
    ],
    question: {
      prompt:
        "At the same number of rays, the low-discrepancy picture of the floor is the closest to its reference and the random one the farthest. Yet on the path-traced Cornell box the three are about equally far from theirs. Why?",
      choices: [
        "Low-discrepancy points only work for ray tracing with a point light",
        "The sampler chooses only where each ray crosses the pixel; most of the box's noise comes from the bounce directions and the points on the light, which are the same for all three",
        "The Cornell box was rendered with fewer rays per pixel",
        "The path tracer averages the three samplers together",
      ],
      answer: 1,
      explain:
        "On the floor, the film position is the only random choice, and a pixel's error comes from the edges (of the checks, the ball, the poles) that cross it. Random points leave gaps and clumps, so the error of their average falls only as 1/√n: 4 times the rays, half the noise. Stratification puts one point in each cell, so only the cells an edge crosses contribute to the error, and it falls faster. Low-discrepancy points are stratified in every shape at once (4 × 4 cells, 2 × 8, 16 thin columns, 16 thin rows), so an edge at any angle is met evenly; and every first 4, 8, 16, … points are spread that way, so a progressive render is even at each pass. In the box most pixels see no edge: their noise is the choice of each bounce's direction and of a point on the light, and changing where the rays cross the pixel does not change it; only the few pixels on an edge gain. The renderer's bounces already take their own low-discrepancy points, whatever the sampler.",
    },
  },
  {
    id: "radiosity",
    title: "Radiosity: flat vs smooth vs two-pass",
    scene: "cornell_radiosity",
    // 16 rays per pixel and 4 shadow rays each: two-pass's shadows are clean, so they can be compared with the patches'
    // (the solve's 0.5 s is most of every panel's cost; flat and smooth trace no shadow rays)
    set: { "sampler.spp": 16, "render.light_samples": 4, "render.radiosity.rays": 1024 },
    stepper: true,
    text: "Radiosity cuts the diffuse surfaces into patches and solves how much light each patch sends to every other: a form factor is the share of the light leaving one patch that lands on another, here estimated by casting rays from it. The solve is progressive refinement: the patch with the most light not yet sent on (its unshot power) shoots it to the others, again and again. A patch's radiosity is the light leaving it per unit area. Flat shows each patch's radiosity as it is, tiles and all; smooth blends it across each patch from values at its corners (Gouraud shading, as for the vertex colours of a polygon); two-pass adds a ray-tracing pass that computes direct light, shadows and mirrors per pixel and takes only the light bounced between surfaces from the patches. “Step through the shooting” opens a panel's job in the workspace, where the radiosity view replays the shots one by one.",
    more: [
      reference("the radiosity integrator", "integrators-and-depth"),
      reference("radiosity settings", "radiosity-settings"),
    ],
    controls: [
      {
        key: "patch",
        label: "patch size",
        kind: "select",
        choices: values(0.5, 0.35, 0.25),
        value: 0.35,
        path: "render.radiosity.patch_size",
      },
    ],
    panels: [
      { label: "flat: one colour per patch", set: { "render.radiosity.display": "flat" } },
      { label: "smooth: interpolated", set: { "render.radiosity.display": "smooth" } },
      { label: "two-pass: radiosity + ray tracing", set: { "render.radiosity.display": "two-pass" } },
    ],
    question: {
      prompt: "Why are the shadows of the blocks sharper in the two-pass picture than in the flat one?",
      choices: [
        "Two-pass uses smaller patches",
        "In two-pass the direct light and its shadows are traced for each pixel; only the bounced light comes from the patches",
        "Two-pass shoots more rays per patch",
      ],
      answer: 1,
      explain:
        "A patch has one radiosity for its whole area, so a shadow edge that crosses a patch is smeared over it. The two-pass method computes the light that comes straight from the lamp with shadow rays at each pixel's own point, and uses the patches only for the light bounced between surfaces, which changes slowly.",
    },
  },
];
