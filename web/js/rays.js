// How rays look, in every view (diagram, overlay, 3D) and the legend, and what their fields mean in words.
import { h, s } from "./util.js";

export const RAY_STYLES = {
  eye: { label: "eye ray", colour: "#ff9f1c", dash: [], width: 2.6 },
  reflection: { label: "reflection ray", colour: "#44a8ff", dash: [], width: 2.2 },
  transmission: { label: "transmission ray", colour: "#2ee6a6", dash: [10, 3, 2, 3], width: 2.2 },
  shadow: { label: "shadow ray, reached the light", colour: "#ffe14d", dash: [6, 4], width: 1.6 },
  blocked: { label: "shadow ray, blocked", colour: "#ff4d6d", dash: [2, 3], width: 1.6 },
};

/** "1 eye ray", "3 reflection rays", "2 shadow rays reaching the light": a count of one style of ray. */
export function countRays(key, n) {
  const noun = {
    shadow: ["shadow ray reaching the light", "shadow rays reaching the light"],
    blocked: ["blocked shadow ray", "blocked shadow rays"],
  }[key];
  const [one, many] = noun || [RAY_STYLES[key].label, `${RAY_STYLES[key].label}s`];
  return `${n} ${n === 1 ? one : many}`;
}

/** The style key of a ray-tree node: its kind, and for shadow rays whether they were blocked. */
export function styleKey(node) {
  if (node.kind === "shadow") return node.occluded ? "blocked" : "shadow";
  return RAY_STYLES[node.kind] ? node.kind : "reflection";
}

export const END_WORDS = {
  miss: "missed: left the scene (returns the background)",
  max_depth: "max depth: a reflection or transmission ray was wanted, but depth + 1 > max_depth",
  min_weight: "min weight: every wanted child's weight fell below min_weight",
  tir: "total internal reflection: no transmission ray",
  light: "reached the light",
  absorbed: "absorbed: kr = kt = 0 here, no reflection or transmission ray",
  max_tree_rays:
    "max tree rays: a reflection or transmission ray was wanted, but the sample had traced its max_tree_rays eye, reflection and transmission rays",
};

/** Why a node ended, in words (shadow rays that were blocked read "blocked"). */
export function endWords(node, short = false) {
  if (!node.end) return short ? "" : "—";
  if (node.kind === "shadow" && node.end === "absorbed") return short ? "blocked" : "blocked before the light";
  if (short)
    return (
      {
        max_depth: "max depth",
        max_tree_rays: "max tree rays",
        min_weight: "min weight",
        tir: "total internal refl.",
        light: "reached light",
      }[node.end] || node.end
    );
  return END_WORDS[node.end] || node.end;
}

/** The legend of ray styles (an SVG line sample and a label each). */
export function legend() {
  return h(
    "ul",
    { class: "legend", "aria-label": "Ray colours" },
    Object.entries(RAY_STYLES).map(([key, st]) =>
      h(
        "li",
        { dataset: { kind: key } },
        s(
          "svg",
          { width: 34, height: 10, viewBox: "0 0 34 10", "aria-hidden": "true" },
          s("line", {
            x1: 1,
            y1: 5,
            x2: 33,
            y2: 5,
            stroke: "#000",
            "stroke-width": st.width + 2,
            "stroke-linecap": "round",
          }),
          s("line", {
            x1: 1,
            y1: 5,
            x2: 33,
            y2: 5,
            stroke: st.colour,
            "stroke-width": st.width,
            "stroke-dasharray": st.dash.join(" ") || null,
          }),
        ),
        st.label,
      ),
    ),
  );
}

/** Draw one styled segment on a 2D canvas, with a dark outline so it reads over any image. */
export function strokeRay(ctx, pts, key, { highlight = false, dim = false } = {}) {
  const st = RAY_STYLES[key];
  const w = st.width * (highlight ? 1.9 : 1);
  ctx.save();
  ctx.globalAlpha = dim ? 0.25 : 1;
  ctx.lineCap = "round";
  ctx.lineJoin = "round";
  ctx.beginPath();
  ctx.moveTo(pts[0][0], pts[0][1]);
  for (let i = 1; i < pts.length; i++) ctx.lineTo(pts[i][0], pts[i][1]);
  ctx.setLineDash([]);
  ctx.strokeStyle = highlight ? "#fff" : "rgba(0, 0, 0, 0.75)";
  ctx.lineWidth = w + (highlight ? 3 : 2);
  ctx.stroke();
  ctx.setLineDash(st.dash.map((d) => d * (highlight ? 1.5 : 1)));
  ctx.strokeStyle = st.colour;
  ctx.lineWidth = w;
  ctx.stroke();
  ctx.restore();
}
