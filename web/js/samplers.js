// Where a sampler puts its rays inside one pixel, drawn large: the grid's cell centres, one random point
// per jittered cell, uniform random points, and the adaptive sampler's corners and centres, subdivided
// where a cell straddles an edge (here a slanted edge crossing the pixel, shaded on one side).

import { fitCanvas } from "./util.js";

/** A small deterministic random generator (mulberry32), so a drawing does not change on every redraw. */
function rng(seed) {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

const inside = (u, v) => 0.78 * u + 0.42 * v > 0.66; // the dark side of the edge

/** Sample positions [u, v] in [0, 1)^2 and cell outlines for a sampler. */
export function samplePositions(sampler, seed = 7) {
  const type = sampler.type || "jittered";
  const spp = sampler.spp ?? 16;
  const n = Math.max(1, Math.round(Math.sqrt(spp)));
  const r = rng(seed);
  const pts = [];
  const cells = [];
  if (type === "center") pts.push([0.5, 0.5]);
  else if (type === "grid" || type === "jittered") {
    for (let j = 0; j < n; j++)
      for (let i = 0; i < n; i++) {
        cells.push([i / n, j / n, 1 / n]);
        pts.push(type === "grid" ? [(i + 0.5) / n, (j + 0.5) / n] : [(i + r()) / n, (j + r()) / n]);
      }
  } else if (type === "random") {
    for (let k = 0; k < spp; k++) pts.push([r(), r()]);
  } else if (type === "adaptive") {
    const maxLevel = sampler.max_level ?? 3;
    const seen = new Set();
    const add = (u, v) => {
      const key = `${u.toFixed(6)},${v.toFixed(6)}`;
      if (!seen.has(key)) {
        seen.add(key);
        pts.push([u, v]);
      }
    };
    const cell = (u, v, size, level) => {
      const five = [
        [u, v],
        [u + size, v],
        [u, v + size],
        [u + size, v + size],
        [u + size / 2, v + size / 2],
      ];
      for (const [a, b] of five) add(a, b);
      cells.push([u, v, size]);
      const values = five.map(([a, b]) => inside(a, b));
      if (level < maxLevel && values.some((x) => x !== values[0])) {
        const hs = size / 2;
        for (const [du, dv] of [
          [0, 0],
          [hs, 0],
          [0, hs],
          [hs, hs],
        ])
          cell(u + du, v + dv, hs, level + 1);
      }
    };
    cell(0, 0, 1, 0);
  }
  return { pts, cells };
}

/** Draw the zoomed pixel with its samples on a canvas (CSS size `size` px). */
export function drawSamples(canvas, sampler, size = 132) {
  const ctx = fitCanvas(canvas, size, size, "#f3f0e6");
  const m = 8;
  const s = size - 2 * m;
  const adaptive = sampler.type === "adaptive";
  if (adaptive) {
    // the edge the adaptive sampler finds: dark on one side
    ctx.fillStyle = "#3b4656";
    ctx.beginPath();
    const u0 = 0.66 / 0.78;
    const u1 = (0.66 - 0.42) / 0.78;
    ctx.moveTo(m + u0 * s, m);
    ctx.lineTo(m + s, m);
    ctx.lineTo(m + s, m + s);
    ctx.lineTo(m + u1 * s, m + s);
    ctx.closePath();
    ctx.fill();
  }
  const { pts, cells } = samplePositions(sampler);
  ctx.strokeStyle = "#8c96a3";
  ctx.lineWidth = 1;
  for (const [u, v, c] of cells) ctx.strokeRect(m + u * s, m + v * s, c * s, c * s);
  ctx.strokeStyle = "#1d2733";
  ctx.lineWidth = 2;
  ctx.strokeRect(m, m, s, s);
  for (const [u, v] of pts) {
    ctx.beginPath();
    ctx.arc(m + u * s, m + v * s, adaptive ? 2.4 : 3.2, 0, 2 * Math.PI);
    ctx.fillStyle = "#ff7a00";
    ctx.strokeStyle = "#fff";
    ctx.lineWidth = 1;
    ctx.fill();
    ctx.stroke();
  }
  canvas.dataset.samples = String(pts.length);
  return pts.length;
}
