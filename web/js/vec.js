// 3-vectors as arrays, the scene's camera (docs/scene-format.md, "Camera rays"), and object transforms.

export const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
export const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
export const mul = (a, k) => [a[0] * k, a[1] * k, a[2] * k];
export const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
export const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
export const length = (a) => Math.sqrt(dot(a, a));
export const normalize = (a) => {
  const l = length(a);
  return l > 0 ? mul(a, 1 / l) : [0, 0, 0];
};
export const lerp = (a, b, t) => add(a, mul(sub(b, a), t));
export const rad = (deg) => (deg * Math.PI) / 180;

/** A scene's number-or-triple as a triple. */
export const triple = (v, fallback = [0, 0, 0]) =>
  Array.isArray(v) ? v : typeof v === "number" ? [v, v, v] : fallback;

/**
 * The camera of a scene for a film of width x height, exactly as the renderer builds eye rays:
 * forward = normalize(lookat - lookfrom), right = normalize(forward x vup), up = right x forward,
 * h = tan(vfov / 2), aspect = width / height.
 */
export function cameraBasis(camera, width, height) {
  const from = camera.lookfrom;
  const forward = normalize(sub(camera.lookat, from));
  const right = normalize(cross(forward, camera.vup || [0, 1, 0]));
  const up = cross(right, forward);
  const h = Math.tan(rad(camera.vfov) / 2);
  return { from, forward, right, up, h, aspect: width / height, width, height };
}

/** The direction of the pinhole ray through film position (fx, fy) (pixel x + u, y + v). */
export function pixelDirection(b, fx, fy) {
  const a = ((2 * fx) / b.width - 1) * b.h * b.aspect;
  const c = (1 - (2 * fy) / b.height) * b.h;
  return normalize(add(add(b.forward, mul(b.right, a)), mul(b.up, c)));
}

/** World point -> film position {x, y} (pixels, x from the left, y from the top) and its depth z along
 * forward; the inverse of pixelDirection for points in front of the camera. */
export function projectToFilm(b, p) {
  const d = sub(p, b.from);
  const z = dot(d, b.forward);
  const sx = dot(d, b.right) / (z * b.h * b.aspect);
  const sy = dot(d, b.up) / (z * b.h);
  return { x: ((sx + 1) / 2) * b.width, y: ((1 - sy) / 2) * b.height, z };
}

/** Clip the segment p-q to the half-space in front of a camera (depth >= near along `forward` from
 * `from`); null when nothing is left. */
export function clipNear(p, q, from, forward, near) {
  const zp = dot(sub(p, from), forward);
  const zq = dot(sub(q, from), forward);
  if (zp < near && zq < near) return null;
  if (zp >= near && zq >= near) return [p, q];
  const t = (near - zp) / (zq - zp);
  const m = lerp(p, q, t);
  return zp < near ? [m, q] : [p, m];
}

/** The 4x4 (row-major, as nested arrays) of a transform: scale, rotate about X then Y then Z (degrees),
 * translate (tracer/kernels/compile.py transform_matrix). */
export function transformMatrix(t) {
  const I = [
    [1, 0, 0, 0],
    [0, 1, 0, 0],
    [0, 0, 1, 0],
    [0, 0, 0, 1],
  ];
  if (!t) return I;
  const sc = triple(t.scale ?? 1, [1, 1, 1]);
  const [rx, ry, rz] = (t.rotate || [0, 0, 0]).map(rad);
  const [cx, sx, cy, sy, cz, sz] = [Math.cos(rx), Math.sin(rx), Math.cos(ry), Math.sin(ry), Math.cos(rz), Math.sin(rz)];
  const S = [
    [sc[0], 0, 0, 0],
    [0, sc[1], 0, 0],
    [0, 0, sc[2], 0],
    [0, 0, 0, 1],
  ];
  const X = [
    [1, 0, 0, 0],
    [0, cx, -sx, 0],
    [0, sx, cx, 0],
    [0, 0, 0, 1],
  ];
  const Y = [
    [cy, 0, sy, 0],
    [0, 1, 0, 0],
    [-sy, 0, cy, 0],
    [0, 0, 0, 1],
  ];
  const Z = [
    [cz, -sz, 0, 0],
    [sz, cz, 0, 0],
    [0, 0, 1, 0],
    [0, 0, 0, 1],
  ];
  const tr = t.translate || [0, 0, 0];
  const T = [
    [1, 0, 0, tr[0]],
    [0, 1, 0, tr[1]],
    [0, 0, 1, tr[2]],
    [0, 0, 0, 1],
  ];
  return [T, Z, Y, X, S].reduce(matmul, I);
}

function matmul(a, b) {
  const out = [];
  for (let i = 0; i < 4; i++) {
    out.push([0, 0, 0, 0]);
    for (let j = 0; j < 4; j++) for (let k = 0; k < 4; k++) out[i][j] += a[i][k] * b[k][j];
  }
  return out;
}

export const applyPoint = (m, p) => [0, 1, 2].map((i) => m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3]);

/** Two unit vectors perpendicular to n and to each other. */
export function tangents(n) {
  const a = Math.abs(n[0]) > 0.9 ? [0, 1, 0] : [1, 0, 0];
  const t = normalize(cross(n, a));
  return [t, cross(n, t)];
}
