// The scene as world-space line drawings (objects, lights, the camera) for the 3D view, and the ray
// tree's rays as segments (for the 3D view and the overlay on the image).
import {
  add,
  applyPoint,
  cameraBasis,
  cross,
  dot,
  length,
  mul,
  normalize,
  sub,
  tangents,
  transformMatrix,
  triple,
} from "./vec.js";

const LIGHT = "#ffd23f";
const CAMERA = "#c8a2ff";

function material(scene, m) {
  if (typeof m === "string") return scene.materials?.[m] || {};
  return m && typeof m === "object" ? m : {};
}

/** A wireframe colour that hints at the material: glass pale cyan, mirrors silver, else kd, lifted. */
function objectColour(mat) {
  const kt = Math.max(...triple(mat.kt ?? 0));
  const kr = Math.max(...triple(mat.kr ?? 0));
  if (kt > 0) return "#9fe7ff";
  if (kr > 0.5) return "#dfe6f0";
  let kd = triple(mat.kd ?? 0.5);
  if (mat.texture && mat.texture.type === "checker") kd = triple(mat.texture.color1 ?? 0.8);
  const c = kd.map((x) => Math.round(255 * Math.min(1, 0.35 + 0.75 * Math.sqrt(Math.max(0, Math.min(1, x))))));
  return `rgb(${c[0]}, ${c[1]}, ${c[2]})`;
}

function circle(c, n, r, steps = 40) {
  const [t1, t2] = tangents(normalize(n));
  const pts = [];
  for (let i = 0; i <= steps; i++) {
    const a = (2 * Math.PI * i) / steps;
    pts.push(add(c, add(mul(t1, r * Math.cos(a)), mul(t2, r * Math.sin(a)))));
  }
  return pts;
}

const parallelogram = (c, e1, e2) => [c, add(c, e1), add(add(c, e1), e2), add(c, e2), c];

function boxCorners(o) {
  const m = transformMatrix(o.transform);
  const out = [];
  for (let i = 0; i < 8; i++) {
    const p = [i & 1 ? o.max[0] : o.min[0], i & 2 ? o.max[1] : o.min[1], i & 4 ? o.max[2] : o.min[2]];
    out.push(applyPoint(m, p));
  }
  return out;
}

function boxEdges(corners) {
  const lines = [];
  for (let i = 0; i < 8; i++) for (const bit of [1, 2, 4]) if (!(i & bit)) lines.push([corners[i], corners[i | bit]]);
  return lines;
}

function meshVertices(o) {
  const m = transformMatrix(o.transform);
  return (o.vertices || []).map((v) => applyPoint(m, v));
}

/** Points that bound an object (none for infinite planes). */
function objectPoints(o) {
  switch (o.type) {
    case "sphere":
      return [sub(o.center, [o.radius, o.radius, o.radius]), add(o.center, [o.radius, o.radius, o.radius])];
    case "quad":
      return parallelogram(o.corner, o.edge1, o.edge2);
    case "disk":
      return circle(o.center, o.normal, o.radius, 8);
    case "box":
      return boxCorners(o);
    case "triangle":
      return o.vertices || [];
    case "mesh":
      return o.vertices ? meshVertices(o) : [applyPoint(transformMatrix(o.transform), [0, 0, 0])];
    default:
      return [];
  }
}

function lightPoints(l) {
  switch (l.type) {
    case "point":
    case "spot":
      return [l.position];
    case "quad":
      return parallelogram(l.corner, l.edge1, l.edge2);
    case "disk":
      return [l.center];
    case "sphere":
      return [sub(l.center, [l.radius, l.radius, l.radius]), add(l.center, [l.radius, l.radius, l.radius])];
    default:
      return [];
  }
}

/** Centre and radius of what is worth looking at: finite objects, lights, the camera's target. */
export function sceneBounds(scene) {
  const pts = [];
  for (const o of scene.objects || []) pts.push(...objectPoints(o));
  for (const l of scene.lights || []) pts.push(...lightPoints(l));
  if (scene.camera?.lookat) pts.push(scene.camera.lookat);
  const ok = pts.filter((p) => Array.isArray(p) && p.every(Number.isFinite));
  if (!ok.length) return { centre: [0, 0, 0], radius: 5 };
  const lo = [0, 1, 2].map((i) => Math.min(...ok.map((p) => p[i])));
  const hi = [0, 1, 2].map((i) => Math.max(...ok.map((p) => p[i])));
  const centre = mul(add(lo, hi), 0.5);
  return { centre, radius: Math.max(1, length(sub(hi, lo)) / 2) };
}

/**
 * The scene as labelled polylines: [{pts: [[x,y,z], ...], colour, width, dash, group, label, labelAt}].
 * group is "object", "light" or "camera"; film is {width, height} for the camera's frustum.
 */
export function sceneLines(scene, film) {
  const { centre, radius } = sceneBounds(scene);
  const out = [];
  const push = (pts, colour, group, extra = {}) => out.push({ pts, colour, group, width: 1.2, dash: [], ...extra });
  (scene.objects || []).forEach((o, i) => {
    const first = out.length; // the lines from here on are this object's (`of`: what a click on them picks)
    const colour = objectColour(material(scene, o.material));
    const label = o.name || `${o.type} ${i}`;
    try {
      switch (o.type) {
        case "sphere": {
          const c = o.center;
          const r = o.radius;
          push(circle(c, [0, 1, 0], r), colour, "object", { label, labelAt: add(c, [0, r * 1.05, 0]) });
          push(circle(c, [1, 0, 0], r), colour, "object");
          push(circle(c, [0, 0, 1], r), colour, "object");
          for (const y of [-0.55, 0.55])
            push(circle(add(c, [0, y * r, 0]), [0, 1, 0], r * Math.sqrt(1 - y * y), 32), colour, "object", {
              width: 0.7,
            });
          break;
        }
        case "plane": {
          const n = normalize(o.normal);
          const [t1, t2] = tangents(n);
          const c = sub(centre, mul(n, dot(sub(centre, o.point), n))); // the scene's centre on the plane
          const half = radius * 1.3;
          const k = 8;
          for (let j = -k; j <= k; j++) {
            const f = (j / k) * half;
            push([add(c, add(mul(t1, f), mul(t2, -half))), add(c, add(mul(t1, f), mul(t2, half)))], colour, "object", {
              width: 0.6,
            });
            push([add(c, add(mul(t2, f), mul(t1, -half))), add(c, add(mul(t2, f), mul(t1, half)))], colour, "object", {
              width: 0.6,
            });
          }
          push([c, add(c, mul(n, radius * 0.15))], colour, "object", { label, labelAt: add(c, mul(t1, half * 0.85)) });
          break;
        }
        case "quad":
          push(parallelogram(o.corner, o.edge1, o.edge2), colour, "object", {
            label,
            labelAt: add(o.corner, mul(add(o.edge1, o.edge2), 0.5)),
          });
          break;
        case "disk":
          push(circle(o.center, o.normal, o.radius), colour, "object", { label, labelAt: o.center });
          push([o.center, add(o.center, mul(normalize(o.normal), o.radius * 0.3))], colour, "object");
          break;
        case "box": {
          const corners = boxCorners(o);
          for (const e of boxEdges(corners)) push(e, colour, "object");
          out[out.length - 1].label = label;
          out[out.length - 1].labelAt = corners[7];
          break;
        }
        case "triangle":
          push([...o.vertices, o.vertices[0]], colour, "object", { label, labelAt: o.vertices[2] });
          break;
        case "mesh": {
          if (o.vertices && o.faces) {
            const v = meshVertices(o);
            const seen = new Set();
            let count = 0;
            for (const f of o.faces) {
              for (let a = 0; a < f.length && count < 6000; a++) {
                const i0 = f[a];
                const i1 = f[(a + 1) % f.length];
                const key = i0 < i1 ? `${i0},${i1}` : `${i1},${i0}`;
                if (seen.has(key) || !v[i0] || !v[i1]) continue;
                seen.add(key);
                push([v[i0], v[i1]], colour, "object", { width: 0.8 });
                count++;
              }
            }
            out[out.length - 1].label = label;
            out[out.length - 1].labelAt = v[0];
          } else {
            // a mesh file: its triangles are not loaded here; a marker at its origin, labelled with the file
            const p = applyPoint(transformMatrix(o.transform), [0, 0, 0]);
            const r = radius * 0.06;
            for (const axis of [
              [r, 0, 0],
              [0, r, 0],
              [0, 0, r],
            ])
              push([sub(p, axis), add(p, axis)], colour, "object", { width: 2 });
            push(circle(p, [0, 1, 0], r * 1.6, 16), colour, "object", {
              label: `${label} (${o.file || "mesh"})`,
              labelAt: add(p, [0, r * 2, 0]),
            });
          }
          break;
        }
        default:
          break;
      }
    } catch {
      // a half-typed object (a missing field) is simply not drawn
    }
    for (let k = first; k < out.length; k++) out[k].of = ["objects", i];
  });
  (scene.lights || []).forEach((l, i) => {
    const first = out.length;
    const label = `light ${i} (${l.type})`;
    try {
      const star = (p, r) => {
        for (const axis of [
          [r, 0, 0],
          [0, r, 0],
          [0, 0, r],
        ])
          push([sub(p, axis), add(p, axis)], LIGHT, "light", { width: 2 });
      };
      const r = radius * 0.05;
      switch (l.type) {
        case "point":
          star(l.position, r);
          out[out.length - 1].label = label;
          out[out.length - 1].labelAt = add(l.position, [0, r * 1.5, 0]);
          break;
        case "spot": {
          star(l.position, r);
          const d = normalize(l.direction);
          const len = radius * 0.5;
          const cr = len * Math.tan(((l.cutoff ?? 30) * Math.PI) / 180);
          const ring = circle(add(l.position, mul(d, len)), d, cr, 24);
          push(ring, LIGHT, "light", { dash: [4, 3] });
          for (let k = 0; k < 24; k += 6) push([l.position, ring[k]], LIGHT, "light", { dash: [4, 3] });
          out[out.length - 1].label = label;
          out[out.length - 1].labelAt = l.position;
          break;
        }
        case "directional": {
          const d = normalize(l.direction);
          const [t1, t2] = tangents(d);
          for (const [a, b] of [
            [0, 0],
            [1, 0],
            [-1, 0],
            [0, 1],
            [0, -1],
          ]) {
            const o = add(
              sub(centre, mul(d, radius * 1.1)),
              add(mul(t1, a * radius * 0.25), mul(t2, b * radius * 0.25)),
            );
            const e = add(o, mul(d, radius * 0.4));
            push([o, e], LIGHT, "light", { width: 1.6 });
            push(
              [
                add(e, add(mul(d, -radius * 0.06), mul(t1, radius * 0.03))),
                e,
                add(e, add(mul(d, -radius * 0.06), mul(t1, -radius * 0.03))),
              ],
              LIGHT,
              "light",
            );
          }
          out[out.length - 1].label = label;
          out[out.length - 1].labelAt = sub(centre, mul(d, radius * 1.15));
          break;
        }
        case "quad": {
          const n = normalize(cross(l.edge1, l.edge2));
          const c = add(l.corner, mul(add(l.edge1, l.edge2), 0.5));
          push(parallelogram(l.corner, l.edge1, l.edge2), LIGHT, "light", { width: 2 });
          push([c, add(c, mul(n, radius * 0.12))], LIGHT, "light", { label, labelAt: c });
          break;
        }
        case "disk":
          push(circle(l.center, l.normal, l.radius), LIGHT, "light", { width: 2, label, labelAt: l.center });
          push([l.center, add(l.center, mul(normalize(l.normal), radius * 0.12))], LIGHT, "light");
          break;
        case "sphere":
          push(circle(l.center, [0, 1, 0], l.radius), LIGHT, "light", {
            width: 2,
            label,
            labelAt: add(l.center, [0, l.radius * 1.1, 0]),
          });
          push(circle(l.center, [1, 0, 0], l.radius), LIGHT, "light", { width: 2 });
          push(circle(l.center, [0, 0, 1], l.radius), LIGHT, "light", { width: 2 });
          break;
        default:
          break;
      }
    } catch {
      // not drawn until it is complete
    }
    for (let k = first; k < out.length; k++) out[k].of = ["lights", i];
  });
  try {
    const cam = scene.camera;
    const b = cameraBasis(cam, film.width, film.height);
    const d = Math.max(0.3, Math.min(length(sub(cam.lookat, cam.lookfrom)), radius) * 0.3);
    const c = add(b.from, mul(b.forward, d));
    const x = mul(b.right, d * b.h * b.aspect);
    const y = mul(b.up, d * b.h);
    const corners = [add(add(c, x), y), add(sub(c, x), y), sub(sub(c, x), y), sub(add(c, x), y)];
    push([...corners, corners[0]], CAMERA, "camera", { width: 1.4, label: "camera", labelAt: b.from });
    for (const k of corners) push([b.from, k], CAMERA, "camera", { width: 1 });
    push([add(c, y), add(c, mul(y, 1.35))], CAMERA, "camera", { width: 1.4 }); // which way is up on the film
    if (cam.lens_radius > 0) push(circle(b.from, b.forward, cam.lens_radius, 24), CAMERA, "camera", { width: 1 });
  } catch {
    // no camera drawn for a half-written camera
  }
  for (const o of scene.objects || []) {
    if (!Array.isArray(o.velocity) || !o.velocity.some((v) => v !== 0)) continue;
    const pts = objectPoints(o);
    if (!pts.length) continue;
    const c = mul(pts.reduce(add, [0, 0, 0]), 1 / pts.length);
    push([c, add(c, o.velocity)], "#b0b8c4", "object", {
      dash: [3, 3],
      label: "velocity",
      labelAt: add(c, o.velocity),
    });
  }
  return out;
}

/** The distance where a ray meets an area light's surface (for shadow rays that reached it), else null. */
function lightDistance(l, o, d) {
  if (!l) return null;
  if (l.type === "point" || l.type === "spot") return length(sub(l.position, o));
  if (l.type === "quad" || l.type === "disk") {
    const n = l.type === "quad" ? cross(l.edge1, l.edge2) : l.normal;
    const p = l.type === "quad" ? l.corner : l.center;
    const den = dot(d, n);
    if (Math.abs(den) < 1e-12) return null;
    const t = dot(sub(p, o), n) / den;
    return t > 0 ? t : null;
  }
  if (l.type === "sphere") {
    const oc = sub(o, l.center);
    const b = dot(oc, d);
    const c = dot(oc, oc) - l.radius * l.radius;
    const disc = b * b - c;
    if (disc < 0) return null;
    const t = -b - Math.sqrt(disc);
    return t > 0 ? t : -b + Math.sqrt(disc);
  }
  return null; // directional: infinitely far
}

/** Each node's segment {p, q, open}: from its origin to its hit, to the light it reached, or (open:
 * a ray that left the scene, or went to a directional light) a fixed `missLength` along it. */
export function raySegments(tree, scene, missLength) {
  const out = new Map();
  for (const n of tree.nodes) {
    const d = normalize(n.direction);
    let t = n.t;
    let open = false;
    if (t === null || t === undefined) {
      if (n.kind === "shadow" && !n.occluded) t = lightDistance((scene.lights || [])[n.light], n.origin, d);
      if (t === null || t === undefined) {
        t = missLength;
        open = true;
      }
    }
    out.set(n.id, { p: n.origin, q: add(n.origin, mul(d, t)), open });
  }
  return out;
}
