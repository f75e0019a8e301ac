// What the Build panel and the 3D view's handles change in a scene, as writes [path, value] into the JSON text
// (jsonpos.js's setValue), so that a move or a scale is one step of the editor's history; where a new object
// or light goes; and which object or light the eye ray through a pixel meets first (picking in the picture).
// Fields as in docs/scene-format.md: a sphere's `center`, a plane's `point`, a quad's `corner` and edges, ...
import {
  add,
  applyPoint,
  cameraBasis,
  cross,
  dot,
  length,
  mul,
  normalize,
  pixelDirection,
  sub,
  transformMatrix,
} from "./vec.js";

export const r3 = (x) => Math.round(x * 1000) / 1000; // what a student would type: millimetres in a scene of metres
export const v3 = (v) => v.map(r3);
const centroid = (pts) => mul(pts.reduce(add, [0, 0, 0]), 1 / pts.length);
const isVec = (v) => Array.isArray(v) && v.length === 3 && v.every(Number.isFinite);

/** The object or light at `of` (["objects", 2] or ["lights", 0]) of a scene, or null. */
export function itemAt(scene, of) {
  const list = scene && Array.isArray(scene[of?.[0]]) ? scene[of[0]] : [];
  const item = list[of?.[1]];
  return item && typeof item === "object" ? item : null;
}

/** Where the handles of an object or light sit (its centre, or the point that places it); null for what has
 * no place (a directional light) or is not complete yet. */
export function anchorOf(o) {
  if (!o) return null;
  let p = null;
  switch (o.type) {
    case "sphere":
    case "disk":
      p = o.center;
      break;
    case "plane":
      p = o.point;
      break;
    case "quad":
      p = isVec(o.corner) && isVec(o.edge1) && isVec(o.edge2) ? add(o.corner, mul(add(o.edge1, o.edge2), 0.5)) : null;
      break;
    case "box":
      p = isVec(o.min) && isVec(o.max) ? applyPoint(transformMatrix(o.transform), mul(add(o.min, o.max), 0.5)) : null;
      break;
    case "triangle":
      p = Array.isArray(o.vertices) && o.vertices.length === 3 && o.vertices.every(isVec) ? centroid(o.vertices) : null;
      break;
    case "mesh":
      p = applyPoint(transformMatrix(o.transform), [0, 0, 0]);
      break;
    case "point":
    case "spot":
      p = o.position;
      break;
    default:
      return null;
  }
  return isVec(p) ? p : null;
}

/** The writes that move `o` (at JSON path `base`) by `d`; null when it cannot move. */
export function moveWrites(o, base, d) {
  const at = (k) => [...base, k];
  const t = o.transform && typeof o.transform === "object" ? o.transform : null;
  switch (o.type) {
    case "sphere":
    case "disk":
      return [[at("center"), v3(add(o.center, d))]];
    case "plane":
      return [[at("point"), v3(add(o.point, d))]];
    case "quad":
      return [[at("corner"), v3(add(o.corner, d))]];
    case "box":
      if (t) return [[[...base, "transform", "translate"], v3(add(isVec(t.translate) ? t.translate : [0, 0, 0], d))]];
      return [
        [at("min"), v3(add(o.min, d))],
        [at("max"), v3(add(o.max, d))],
      ];
    case "triangle":
      return [[at("vertices"), o.vertices.map((v) => v3(add(v, d)))]];
    case "mesh":
      return [[[...base, "transform", "translate"], v3(add(t && isVec(t.translate) ? t.translate : [0, 0, 0], d))]];
    case "point":
    case "spot":
      return [[at("position"), v3(add(o.position, d))]];
    default:
      return null;
  }
}

/** Rotate v about the unit axis u by `a` radians (Rodrigues). */
const turn = (v, u, a) =>
  add(add(mul(v, Math.cos(a)), mul(cross(u, v), Math.sin(a))), mul(u, dot(u, v) * (1 - Math.cos(a))));

/** The writes that aim a light with a `direction` (spot, directional): turned `yaw` degrees about `up` (the
 * scene's vertical) and tilted `pitch` degrees towards it; null for a light without one. A tilt stops 5 degrees
 * short of straight up or down (past it, the beam would flip over and "left" would become "right"). */
export function aimWrites(o, base, yaw, pitch, up = [0, 1, 0]) {
  if (!o || !isVec(o.direction) || length(o.direction) === 0) return null;
  const u = normalize(up);
  let d = turn(normalize(o.direction), u, (yaw * Math.PI) / 180);
  if (pitch) {
    // the tilt's axis is horizontal, across the beam; a beam straight up or down tilts along z
    let side = cross(d, u);
    if (length(side) < 1e-6) side = cross(d, Math.abs(u[2]) < 0.9 ? [0, 0, 1] : [1, 0, 0]);
    const now = Math.asin(Math.max(-1, Math.min(1, dot(d, u))));
    const limit = (85 * Math.PI) / 180;
    const want = Math.max(Math.min(now, -limit), Math.min(Math.max(now, limit), now + (pitch * Math.PI) / 180));
    d = turn(d, normalize(side), want - now);
  }
  return [[[...base, "direction"], v3(normalize(d))]];
}

/** An angle in degrees as a student writes it: to a tenth of a degree, in (-180, 180]. */
const angle = (deg) => {
  const a = Math.round(((((deg + 180) % 360) + 360) % 360) * 10) / 10 - 180;
  return a === -180 ? 180 : a;
};

/** The writes that turn `o` by `deg` degrees about the vertical (y) axis through its anchor, so that it turns
 * in place; null for what does not turn (a sphere, a plane, a light without a shape). A box or a mesh turns by
 * its `transform.rotate` (about y: the angle a student types), its `translate` set so that its centre stays
 * (a transform turns about the origin: docs/scene-format.md); a box without a transform gets one. A quad, a
 * triangle and a disk turn their own vectors. About y exactly when the transform has no z rotation (the order
 * is x, then y, then z); about the box's own tilted axis otherwise. */
export function rotateWrites(o, base, deg) {
  if (!o || !Number.isFinite(deg)) return null;
  const c = anchorOf(o);
  if (!c) return null;
  const up = [0, 1, 0];
  const a = (deg * Math.PI) / 180;
  const spin = (v) => turn(v, up, a);
  const about = (p) => v3(add(c, spin(sub(p, c))));
  const at = (k) => [...base, k];
  switch (o.type) {
    case "box":
    case "mesh": {
      const t = o.transform && typeof o.transform === "object" ? o.transform : {};
      const r = isVec(t.rotate) ? t.rotate : [0, 0, 0];
      const rotate = [r[0], angle(r[1] + deg), r[2]];
      const scale = t.scale ?? 1;
      // the centre in the shape's own frame (a box: its min and max's middle; a mesh: its origin) stays where it is
      const local = o.type === "box" ? mul(add(o.min, o.max), 0.5) : [0, 0, 0];
      const translate = v3(sub(c, applyPoint(transformMatrix({ rotate, scale }), local)));
      return [[[...base, "transform"], t.scale === undefined ? { translate, rotate } : { translate, rotate, scale }]];
    }
    case "quad":
      return [
        [at("corner"), about(o.corner)],
        [at("edge1"), v3(spin(o.edge1))],
        [at("edge2"), v3(spin(o.edge2))],
      ];
    case "triangle":
      return [[at("vertices"), o.vertices.map(about)]];
    case "disk":
      return isVec(o.normal) ? [[at("normal"), v3(spin(o.normal))]] : null;
    default:
      return null;
  }
}

/** The writes that scale `o` by k about its anchor; null for what has no size (a plane, a point light). */
export function scaleWrites(o, base, k) {
  const at = (key) => [...base, key];
  const c = anchorOf(o);
  const about = (p) => v3(add(c, mul(sub(p, c), k)));
  const t = o.transform && typeof o.transform === "object" ? o.transform : null;
  switch (o.type) {
    case "sphere":
    case "disk":
      return [[at("radius"), r3(o.radius * k)]];
    case "quad":
      return [
        [at("corner"), about(o.corner)],
        [at("edge1"), v3(mul(o.edge1, k))],
        [at("edge2"), v3(mul(o.edge2, k))],
      ];
    case "box":
      if (t) {
        const s = t.scale ?? 1;
        return [[[...base, "transform", "scale"], Array.isArray(s) ? v3(mul(s, k)) : r3(s * k)]];
      }
      return [
        [at("min"), v3(add(mul(add(o.min, o.max), 0.5), mul(sub(o.min, o.max), 0.5 * k)))],
        [at("max"), v3(add(mul(add(o.min, o.max), 0.5), mul(sub(o.max, o.min), 0.5 * k)))],
      ];
    case "triangle":
      return [[at("vertices"), o.vertices.map(about)]];
    case "mesh": {
      const s = t?.scale ?? 1;
      return [[[...base, "transform", "scale"], Array.isArray(s) ? v3(mul(s, k)) : r3(s * k)]];
    }
    default:
      return null;
  }
}

// -- picking: the eye ray through a pixel, against the scene's shapes --------------------------------

function hitSphere(c, r, o, d) {
  const oc = sub(o, c);
  const b = dot(oc, d);
  const disc = b * b - (dot(oc, oc) - r * r);
  if (disc < 0) return null;
  const s = Math.sqrt(disc);
  return -b - s > 1e-6 ? -b - s : -b + s > 1e-6 ? -b + s : null;
}

function hitPlane(p, n, o, d) {
  const den = dot(d, n);
  if (Math.abs(den) < 1e-12) return null;
  const t = dot(sub(p, o), n) / den;
  return t > 1e-6 ? t : null;
}

function hitQuad(corner, e1, e2, o, d) {
  const n = cross(e1, e2);
  const t = hitPlane(corner, n, o, d);
  if (t === null) return null;
  const p = sub(add(o, mul(d, t)), corner);
  const w = mul(n, 1 / dot(n, n));
  const a = dot(w, cross(p, e2));
  const b = dot(w, cross(e1, p));
  return a >= 0 && a <= 1 && b >= 0 && b <= 1 ? t : null;
}

function hitDisk(c, n, r, o, d) {
  const t = hitPlane(c, n, o, d);
  return t !== null && length(sub(add(o, mul(d, t)), c)) <= r ? t : null;
}

function hitTriangle([a, b, c], o, d) {
  const e1 = sub(b, a);
  const e2 = sub(c, a);
  const p = cross(d, e2);
  const det = dot(e1, p);
  if (Math.abs(det) < 1e-12) return null;
  const s = sub(o, a);
  const u = dot(s, p) / det;
  const q = cross(s, e1);
  const v = dot(d, q) / det;
  const t = dot(e2, q) / det;
  return u >= 0 && v >= 0 && u + v <= 1 && t > 1e-6 ? t : null;
}

/** The inverse of a 3x3 matrix (rows), or null when it has none. */
function inverse3(a) {
  const c = [cross(a[1], a[2]), cross(a[2], a[0]), cross(a[0], a[1])]; // columns of the adjugate
  const det = dot(a[0], c[0]);
  if (Math.abs(det) < 1e-15) return null;
  return [0, 1, 2].map((i) => [c[0][i] / det, c[1][i] / det, c[2][i] / det]);
}

const times = (m, v) => [dot(m[0], v), dot(m[1], v), dot(m[2], v)];

/** A box's slabs, in the box's own frame when it has a transform (the ray taken through the inverse of its
 * matrix: the same t along it, since the map is affine), so a rotated box is picked where it is drawn. */
function hitBox(o, orig, d) {
  const m = transformMatrix(o.transform);
  const inv = inverse3(m.slice(0, 3).map((row) => row.slice(0, 3)));
  if (!inv) return null;
  const lo = times(inv, sub(orig, [m[0][3], m[1][3], m[2][3]]));
  const ld = times(inv, d);
  let near = -Infinity;
  let far = Infinity;
  for (let k = 0; k < 3; k++) {
    const [a, b] = [Math.min(o.min[k], o.max[k]), Math.max(o.min[k], o.max[k])];
    if (Math.abs(ld[k]) < 1e-12) {
      if (lo[k] < a || lo[k] > b) return null;
      continue;
    }
    const [t1, t2] = [(a - lo[k]) / ld[k], (b - lo[k]) / ld[k]].sort((x, y) => x - y);
    near = Math.max(near, t1);
    far = Math.min(far, t2);
  }
  if (near > far) return null;
  return near > 1e-6 ? near : far > 1e-6 ? far : null;
}

/** The distance along the ray (o, unit d) to an object or an area light, or null. */
function hit(x, o, d) {
  try {
    switch (x.type) {
      case "sphere":
        return hitSphere(x.center, x.radius, o, d);
      case "plane":
        return hitPlane(x.point, x.normal, o, d);
      case "quad":
        return hitQuad(x.corner, x.edge1, x.edge2, o, d);
      case "disk":
        return hitDisk(x.center, x.normal, x.radius, o, d);
      case "box":
        return hitBox(x, o, d);
      case "triangle":
        return hitTriangle(x.vertices, o, d);
      case "mesh": {
        if (!Array.isArray(x.vertices) || !Array.isArray(x.faces)) return null;
        const m = transformMatrix(x.transform);
        const v = x.vertices.map((p) => applyPoint(m, p));
        let best = null;
        for (const f of x.faces)
          for (let k = 1; k + 1 < f.length; k++) {
            const t = hitTriangle([v[f[0]], v[f[k]], v[f[k + 1]]], o, d);
            if (t !== null && (best === null || t < best)) best = t;
          }
        return best;
      }
      default:
        return null;
    }
  } catch {
    return null; // a half-typed shape is not there
  }
}

/** What the eye ray through film position (fx, fy) of a width x height film meets first: {of, t} with of =
 * ["objects", i] or ["lights", i] (area lights are visible), or null. The pinhole ray, as the renderer's. */
export function pickAt(scene, fx, fy, width, height) {
  const b = cameraBasis(scene.camera, width, height);
  return firstHit(scene, b.from, pixelDirection(b, fx, fy));
}

/** The object or area light the ray (o, unit d) meets first: {of, t}, or null. */
export function firstHit(scene, o, d) {
  let best = null;
  for (const key of ["objects", "lights"])
    (Array.isArray(scene[key]) ? scene[key] : []).forEach((x, i) => {
      const t = x && typeof x === "object" ? hit(x, o, d) : null;
      if (t !== null && (!best || t < best.t)) best = { of: [key, i], t };
    });
  return best;
}

// -- where new things go: in front of the camera, on the floor when there is one ---------------------

/** The scene's scale (the camera's distance to what it looks at, over the examples' 6.5) and its frame. */
export function stage(scene) {
  const cam = scene.camera || {};
  const from = isVec(cam.lookfrom) ? cam.lookfrom : [0, 1, 6];
  const at = isVec(cam.lookat) ? cam.lookat : [0, 1, 0];
  const up = normalize(isVec(cam.vup) ? cam.vup : [0, 1, 0]);
  const forward = normalize(sub(at, from));
  const right = normalize(cross(forward, up));
  const scale = Math.max(0.05, length(sub(at, from)) / 6.5);
  return { at, up, right, toward: mul(forward, -1), scale, step: nice(0.1 * scale) };
}

/** The round number (1, 2 or 5 times a power of ten) nearest x: a key's step that adds up to round positions. */
function nice(x) {
  const p = 10 ** Math.floor(Math.log10(x));
  return [1, 2, 5, 10].map((k) => k * p).reduce((a, b) => (Math.abs(b - x) < Math.abs(a - x) ? b : a));
}

/** The heights (along up) of the highest floor below what the camera looks at and of the lowest ceiling above
it: planes and quads facing up or down (a Cornell box's floor and ceiling); null where there is none. */
export function floorAndCeiling(scene) {
  const { at, up } = stage(scene);
  const eye = dot(at, up);
  let floor = null;
  let ceiling = null;
  for (const o of Array.isArray(scene.objects) ? scene.objects : []) {
    const p = o?.type === "plane" ? o.point : o?.type === "quad" ? o.corner : null;
    const n =
      o?.type === "plane"
        ? o.normal
        : o?.type === "quad" && isVec(o.edge1) && isVec(o.edge2)
          ? cross(o.edge1, o.edge2)
          : null;
    if (!isVec(p) || !isVec(n) || Math.abs(dot(normalize(n), up)) < 0.9) continue;
    const y = dot(p, up);
    if (y < eye && (floor === null || y > floor)) floor = y;
    if (y > eye && (ceiling === null || y < ceiling)) ceiling = y;
  }
  return { floor, ceiling };
}

export const floorHeight = (scene) => floorAndCeiling(scene).floor;

/** How far from its anchor an object reaches (a bounding sphere's radius), for keeping new things apart. */
function reach(o) {
  switch (o?.type) {
    case "sphere":
    case "disk":
      return Number.isFinite(o.radius) ? o.radius : null;
    case "box":
      return isVec(o.min) && isVec(o.max) ? length(sub(o.max, o.min)) / 2 : null;
    case "quad":
      return isVec(o.edge1) && isVec(o.edge2)
        ? Math.max(length(add(o.edge1, o.edge2)), length(sub(o.edge1, o.edge2))) / 2
        : null;
    default:
      return null; // planes (infinite), meshes and triangles: not in the way of a new thing
  }
}

/** A place for a new thing that reaches r from its centre: on the floor (or at the look-at point), near the middle
of the view but clear of what is already there (spheres, boxes, panels about its size; a wall or a large platform
is scenery to stand in, not a neighbour) and on the inner side of the walls (upright planes and large quads, a
Cornell box's): the nearest free spot of a grid in the floor's plane, side to side first, then in depth. */
export function freeSpot(scene, r) {
  const { at, up, right, toward, scale } = stage(scene);
  const floor = floorHeight(scene);
  const base = floor === null ? at : add(at, mul(up, floor + r - dot(at, up)));
  const objects = Array.isArray(scene.objects) ? scene.objects : [];
  const taken = objects.map((o) => [anchorOf(o), reach(o)]).filter(([c, k]) => c && k !== null && k <= 1.5 * scale);
  const walls = [];
  for (const o of objects) {
    const p = o?.type === "plane" ? o.point : o?.type === "quad" && (reach(o) ?? 0) > 1.5 * scale ? o.corner : null;
    const n = o?.type === "plane" ? o.normal : o?.type === "quad" ? cross(o.edge1, o.edge2) : null;
    if (!isVec(p) || !isVec(n) || Math.abs(dot(normalize(n), up)) > 0.1) continue;
    const side = Math.sign(dot(sub(at, p), n)) || 1; // the wall's side where the camera looks
    walls.push({ p, n: mul(normalize(n), side) });
  }
  const free = (q) =>
    taken.every(([c, k]) => length(sub(c, q)) >= k + r) && walls.every(({ p, n }) => dot(sub(q, p), n) >= r);
  const depth = normalize(sub(toward, mul(up, dot(toward, up)))); // towards the camera, along the floor
  const d = 0.5 * r;
  const spots = [];
  for (let i = -16; i <= 16; i++) for (let j = -8; j <= 8; j++) spots.push([i, j, Math.hypot(i, 2 * j)]);
  spots.sort((a, b) => a[2] - b[2]);
  for (const [i, j] of spots) {
    const q = add(base, add(mul(right, i * d), mul(depth, -j * d)));
    if (free(q)) return v3(q);
  }
  return v3(base);
}
