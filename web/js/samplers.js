// One pixel's samples drawn large, where the renderer puts them. POST /api/samples (tracer/samples.py) gives
// each sample's film position inside the pixel, computed by the renderer's own sampling code for the
// scene, the pixel and the seed: the grid's cell centres, one random point per jittered cell, uniform random
// points, and for the adaptive sampler the cells it visited (each filled with the mean colour of its
// corners and centre, as the PNG shows it) and the grid points it traced.

import { fitCanvas } from "./util.js";

/** Draw the answer of POST /api/samples (`listed`; null: the empty pixel) on a canvas of CSS size `size` px.
 * Returns the number of sample points drawn (also kept in the canvas's data-samples). */
export function drawSamples(canvas, listed, size = 132) {
  const ctx = fitCanvas(canvas, size, size, "#f3f0e6");
  const adaptive = listed?.sampler === "adaptive";
  const pts = (listed?.samples || []).filter((s) => !adaptive || s.traced).map((s) => s.position);
  // the drawing spans the pixel, and beyond it when a wide filter puts samples in the neighbours' area
  const lo = Math.min(0, ...pts.flat());
  const hi = Math.max(1, ...pts.flat());
  const m = 8;
  const s = (size - 2 * m) / (hi - lo);
  const X = (u) => m + (u - lo) * s;
  for (const c of listed?.cells || []) {
    if (c.split) continue;
    ctx.fillStyle = c.srgb; // a cell that was not split: the mean of its five colours
    ctx.fillRect(X(c.corner[0]), X(c.corner[1]), c.size * s, c.size * s);
  }
  ctx.strokeStyle = "#8c96a3";
  ctx.lineWidth = 1;
  for (const c of listed?.cells || []) ctx.strokeRect(X(c.corner[0]), X(c.corner[1]), c.size * s, c.size * s);
  const n = listed?.strata;
  if (n) for (let j = 0; j < n; j++) for (let i = 0; i < n; i++) ctx.strokeRect(X(i / n), X(j / n), s / n, s / n);
  ctx.strokeStyle = "#1d2733";
  ctx.lineWidth = 2;
  ctx.strokeRect(X(0), X(0), s, s);
  for (const [u, v] of pts) {
    ctx.beginPath();
    ctx.arc(X(u), X(v), adaptive ? 2.4 : 3.2, 0, 2 * Math.PI);
    ctx.fillStyle = "#ff7a00";
    ctx.strokeStyle = "#fff";
    ctx.lineWidth = 1;
    ctx.fill();
    ctx.stroke();
  }
  canvas.dataset.samples = String(pts.length);
  canvas.dataset.positions = JSON.stringify(pts);
  return pts.length;
}

/** The samples in words, under the drawing. */
export function samplerWords(listed) {
  const n = listed.samples.length;
  switch (listed.sampler) {
    case "center":
      return "one ray through the centre";
    case "grid":
      return `${n} rays at the cell centres of a regular grid`;
    case "jittered":
      return `${n} rays, one at a random point of each cell`;
    case "random":
      return `${n} rays at uniform random points`;
    case "lowdiscrepancy":
      return `${n} rays at successive points of a low-discrepancy sequence`;
    case "adaptive": {
      const traced = listed.samples.filter((s) => s.traced).length;
      return `${traced} rays: a cell is split where its colours differ, down to level ${listed.max_level}`;
    }
    default:
      return `${n} rays`;
  }
}
