// One pixel's samples drawn large, where the renderer puts them. POST /api/samples (tracer/tools/pixel_samples.py) gives
// each sample's film position inside the pixel, computed by the renderer's own sampling code for the
// scene, the pixel and the seed: the grid's cell centres, one random point per jittered cell, uniform random
// points, the successive points of a pixel's low-discrepancy sequence, and for the adaptive sampler the
// cells it visited (each filled with the mean colour of its corners and centre, as the PNG shows it) and
// the grid points it traced. For n = m² random or low-discrepancy points the m x m grid is drawn too, as
// a guide, and the words under the drawing count how many of its cells, and of the n columns and n rows
// of width 1/n, the points leave empty (a (0,k,2)-net leaves none; jittered points none of the cells).

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
  const n = listed?.strata || guideCells(listed);
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

/** The side m of the m x m grid drawn over n = m² (> 1) random or low-discrepancy points inside the pixel; else 0. */
function guideCells(listed) {
  if (!["random", "lowdiscrepancy"].includes(listed?.sampler)) return 0;
  return evenness(listed.samples.map((s) => s.position))?.m || 0;
}

/** How evenly n = m² points (inside the pixel) cover it: the empty cells of the m x m grid, and the empty
 * columns and rows of width 1/n (null: not a square count, or points outside the pixel). */
export function evenness(pts) {
  const n = pts.length;
  const m = Math.round(Math.sqrt(n));
  if (m < 2 || m * m !== n || !pts.every(([u, v]) => u >= 0 && u < 1 && v >= 0 && v < 1)) return null;
  const cells = new Set(pts.map(([u, v]) => Math.floor(v * m) * m + Math.floor(u * m)));
  const columns = new Set(pts.map(([u]) => Math.floor(u * n)));
  const rows = new Set(pts.map(([, v]) => Math.floor(v * n)));
  return { n, m, emptyCells: m * m - cells.size, emptyColumns: n - columns.size, emptyRows: n - rows.size };
}

/** `evenness` in words: ". One in each of the 4 × 4 cells, 16 columns and 16 rows (strips 1/16 wide)." */
function evennessWords(pts) {
  const e = evenness(pts);
  if (!e) return "";
  const { n, m, emptyCells, emptyColumns, emptyRows } = e;
  if (!emptyCells && !emptyColumns && !emptyRows)
    return `. One in each of the ${m} × ${m} cells, ${n} columns and ${n} rows (strips 1/${n} wide).`;
  return `. Empty: ${emptyCells} of the ${m} × ${m} cells, ${emptyColumns} of ${n} columns, ${emptyRows} of ${n} rows (strips 1/${n} wide).`;
}

/** The samples in words, under the drawing. */
export function samplerWords(listed) {
  const n = listed.samples.length;
  const even = () => evennessWords(listed.samples.map((s) => s.position));
  switch (listed.sampler) {
    case "center":
      return "one ray through the centre";
    case "grid":
      return `${n} rays at the cell centres of a regular grid`;
    case "jittered":
      return `${n} rays, one at a random point of each cell${even()}`;
    case "random":
      return `${n} rays at uniform random points${even()}`;
    case "lowdiscrepancy":
      return `${n} rays at successive points of a low-discrepancy sequence${even()}`;
    case "adaptive": {
      const traced = listed.samples.filter((s) => s.traced).length;
      return `${traced} rays: a cell is split where its colours differ, down to level ${listed.max_level}`;
    }
    default:
      return `${n} rays`;
  }
}
