// The lessons on sampling a pixel and the shutter: supersampling, adaptive sampling, temporal aliasing, motion blur.
import { named, reference, values } from "./helpers.js";

export const SAMPLING = [
  {
    id: "sampling",
    title: "One ray per pixel vs supersampling vs adaptive vs jittered",
    samples: [44, 37], // the pixel whose samples are drawn (at 160 x 120): the ball's edge against the sky crosses it
    text: "The same scene sampled four ways; under each, where the sampler puts its rays inside one pixel. One ray per pixel gives jaggies, broken thin poles and moiré near the horizon (a frequency too high for the pixels masquerading as a lower one). A regular grid smooths edges but the moiré only moves. Adaptive supersampling starts from the corners and the centre and splits only cells whose colours differ (here across an edge). Jittered sampling (one random point per cell) turns the moiré into noise; how much noise depends on how evenly the points lie (the noise lesson compares random, jittered and low-discrepancy points).",
    more: [reference("the samplers", "sampler"), reference("camera rays", "camera-rays")],
    controls: [
      {
        key: "spp",
        label: "rays per pixel (grid and jittered)",
        kind: "select",
        choices: values(4, 16, 64),
        value: 16,
        panels: [1, 3],
        path: "sampler.spp",
      },
    ],
    panels: [
      { label: "one ray per pixel (center)", scene: "antialias_center" },
      {
        label: (s) => `supersampling: ${Math.sqrt(s.sampler.spp)} × ${Math.sqrt(s.sampler.spp)} grid`,
        scene: "antialias_grid",
      },
      { label: "adaptive supersampling", scene: "antialias_adaptive" },
      {
        label: (s) => `stochastic: jittered ${Math.sqrt(s.sampler.spp)} × ${Math.sqrt(s.sampler.spp)}`,
        scene: "antialias_jittered",
      },
    ],
    question: {
      prompt: "Which picture turns the moiré of the checkered floor near the horizon into noise?",
      choices: ["one ray per pixel", "the regular grid", "adaptive supersampling", "jittered sampling"],
      answer: 3,
      explain:
        "Regular samples (one per pixel, a grid, or the adaptive sampler's grid points) line up with the regular checks and alias them into false patterns. Jittered samples are random inside their cells: the error no longer repeats from pixel to pixel, so the eye sees fine noise instead of a pattern, and more rays make that noise smaller.",
    },
  },
  {
    id: "aliasing",
    title: "Adaptive supersampling: where the rays go",
    scene: "antialias_adaptive",
    raysMap: true,
    text: "The adaptive sampler traces the 4 corners and the centre of each pixel; where those colours differ by more than the threshold the pixel is cut into 4 cells, each sampled the same way, down to max_level. Under each picture, its rays per pixel (white: many). The rays gather on edges and the poles, but a cell can look uniform while it spans several checks of the floor near the horizon: there the sampling grid meets a regular structure and still aliases. Adaptive stochastic sampling (jitter) moves the grid points at random inside their cells, which turns that aliasing into noise.",
    more: [reference("the adaptive sampler", "sampler")],
    controls: [
      {
        key: "threshold",
        label: "threshold",
        kind: "select",
        choices: values(0.01, 0.05, 0.1, 0.3),
        value: 0.05,
        panels: [0, 1],
        path: "sampler.threshold",
      },
      {
        key: "level",
        label: "max_level",
        kind: "range",
        min: 1,
        max: 4,
        step: 1,
        value: 3,
        panels: [0, 1],
        path: "sampler.max_level",
      },
    ],
    panels: [
      { label: "adaptive supersampling" },
      { label: "adaptive stochastic (jitter)", set: { "sampler.jitter": true } },
      { label: "picture A", reveal: "picture A: jittered, 16 rays in every pixel", scene: "antialias_jittered" },
      { label: "picture B", reveal: "picture B: adaptive, threshold 0.1", set: { "sampler.threshold": 0.1 } },
    ],
    question: {
      prompt:
        "Pictures A and B were made by two different samplers. Which one used the adaptive sampler? (Look at their rays per pixel.)",
      choices: ["picture A", "picture B"],
      answer: 1,
      explain:
        "B's count changes from pixel to pixel: many rays along the edges of the ball, the poles and the checks, few in flat regions; only the adaptive sampler does that. A's map has just two flat levels: 16 eye rays in every pixel, plus a shadow ray for each one that hits something (the sky has none). That is a fixed-rate sampler, here jittered.",
    },
  },
  {
    id: "temporal",
    title: "Temporal aliasing: instants vs a time per ray",
    scene: "temporal",
    set: { "sampler.type": "jittered" },
    text: "Time is sampled too. A single instant shows a fast ball frozen (a strobe). Averaging N instants (frames at 120 Hz averaged into one, camera.instants = N) shows N separate copies: the time samples are regular, so fast motion aliases. Giving every ray its own random time in the shutter (distributed ray tracing) makes one continuous streak, noisy where there are few rays. All three pictures cost the same number of rays.",
    more: [reference("the camera's shutter and instants", "camera"), reference("camera rays", "camera-rays")],
    controls: [
      {
        key: "n",
        label: "instants N (middle)",
        kind: "select",
        choices: values(2, 4, 8),
        value: 4,
        panels: [1],
        path: "camera.instants",
      },
      {
        key: "spp",
        label: "rays per pixel (all)",
        kind: "select",
        choices: values(4, 16, 64),
        value: 16,
        path: "sampler.spp",
      },
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
      explain:
        "Averaging N instants samples time at N regular points: the ball is seen at N places and nowhere between, a strobe (temporal aliasing). One instant shows one sharp ball and no motion at all. A random time per ray covers the whole shutter interval, so the copies melt into a streak; too few rays leave noise instead of copies.",
    },
  },
  {
    id: "motion",
    title: "Motion blur: the object, its shadow, its reflection",
    scene: "motion_blur",
    set: { "sampler.spp": 16 },
    edit: (s) => delete named(s, "falling box").velocity, // one motion at a time: the red ball's
    text: "Each eye ray gets its own time while the shutter is open, and moving objects are where they are at that time; the shadow and reflection rays it spawns share that time. So the moving red ball blurs, and so do its shadow on the floor and its image in the mirror behind. Only the red ball moves here (the example's falling box is held still); the still version is the same scene with every velocity removed.",
    more: [reference("camera rays and their time", "camera-rays"), reference("objects and their velocity", "objects")],
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
      {
        label: "still (velocities removed)",
        edit: (s) => {
          for (const o of s.objects || []) delete o.velocity;
        },
        note: "objects[*].velocity removed",
      },
      { label: (s) => `moving, shutter open ${(s.camera.shutter || [0, 1]).join(" → ")}` },
    ],
    question: {
      prompt: "In the moving picture, what blurs?",
      choices: [
        "only the red ball",
        "the red ball and its shadow",
        "the red ball, its shadow and its reflection in the mirror",
      ],
      answer: 2,
      explain:
        "A shadow ray and a reflection ray carry the time of the eye ray that spawned them, so they meet the ball where it was at that time: the shadow and the mirror image are averaged over the shutter interval as well. What stands still (the blue ball, the box) stays sharp, and so does what it casts.",
    },
  },
];
