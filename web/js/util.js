// Small helpers shared by every part of the page: DOM building, number formatting, storage, debounce.

/** Create an element: h("button", {class: "x", onclick: f}, "text", child). */
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  setAttrs(el, attrs);
  for (const c of children.flat()) {
    if (c === null || c === undefined || c === false) continue;
    el.append(c instanceof Node ? c : String(c));
  }
  return el;
}

const SVG_NS = "http://www.w3.org/2000/svg";

/** Create an SVG element with attributes. */
export function s(tag, attrs = {}, ...children) {
  const el = document.createElementNS(SVG_NS, tag);
  setAttrs(el, attrs);
  for (const c of children.flat()) {
    if (c === null || c === undefined || c === false) continue;
    el.append(c instanceof Node ? c : String(c));
  }
  return el;
}

function setAttrs(el, attrs) {
  for (const [k, v] of Object.entries(attrs)) {
    if (v === null || v === undefined || v === false) continue;
    if (k.startsWith("on") && typeof v === "function") el.addEventListener(k.slice(2), v);
    else if (k === "dataset") Object.assign(el.dataset, v);
    else if (k === "text") el.textContent = v;
    else if (k === "style")
      el.style.cssText = v; // through the CSSOM: the page's content security policy forbids style attributes
    else el.setAttribute(k, v === true ? "" : String(v));
  }
}

export const $ = (sel, root = document) => root.querySelector(sel);
export const $$ = (sel, root = document) => Array.from(root.querySelectorAll(sel));

/** A number in at most `digits` significant figures, without trailing zeros (0.000123 -> "1.23e-4"). */
export function num(x, digits = 3) {
  if (x === null || x === undefined) return "–";
  if (typeof x !== "number" || !Number.isFinite(x)) return String(x);
  if (x === 0) return "0";
  const a = Math.abs(x);
  if (a >= 1e-3 && a < 1e5) return String(Number(x.toPrecision(digits)));
  return x.toExponential(digits - 1).replace(/\.?0+e/, "e");
}

/** An RGB triple as "r g b", or one number when the three are equal. */
export function rgb(v, digits = 3) {
  if (!Array.isArray(v)) return num(v, digits);
  if (v[0] === v[1] && v[1] === v[2]) return num(v[0], digits);
  return v.map((x) => num(x, digits)).join(" ");
}

/** A linear RGB triple as a CSS colour (sRGB curve, clamped): the swatch of a radiance or a weight. */
export function cssColour(v, scale = 1) {
  const c = (Array.isArray(v) ? v : [v, v, v]).map((x) => {
    const l = Math.min(1, Math.max(0, (Number.isFinite(x) ? x : 0) * scale));
    const srgb = l <= 0.0031308 ? 12.92 * l : 1.055 * l ** (1 / 2.4) - 0.055;
    return Math.round(srgb * 255);
  });
  return `rgb(${c[0]}, ${c[1]}, ${c[2]})`;
}

export function seconds(t) {
  if (t === null || t === undefined) return "–";
  if (t < 10) return `${t.toFixed(2)} s`;
  if (t < 120) return `${t.toFixed(1)} s`;
  return `${Math.floor(t / 60)} min ${Math.round(t % 60)} s`;
}

export function integer(n) {
  return Number.isFinite(n) ? n.toLocaleString("en-US") : "–";
}

export function debounce(fn, ms) {
  let timer = null;
  const wrapped = (...args) => {
    clearTimeout(timer);
    timer = setTimeout(() => fn(...args), ms);
  };
  wrapped.flush = (...args) => {
    clearTimeout(timer);
    fn(...args);
  };
  wrapped.cancel = () => clearTimeout(timer);
  return wrapped;
}

/** Is a window "error" event the browser's note that a ResizeObserver's callback changed the layout it watches
 * (the rest is delivered in the next frame, as the specification says): a notice, not an error of the page. */
export function benignError(e) {
  return /^ResizeObserver loop (completed with undelivered notifications|limit exceeded)/.test(e?.message || "");
}

/** localStorage that never throws (private windows, full quota): the page works without it. */
export const store = {
  get(key, fallback = null) {
    try {
      const v = localStorage.getItem(key);
      return v === null ? fallback : JSON.parse(v);
    } catch {
      return fallback;
    }
  },
  set(key, value) {
    try {
      localStorage.setItem(key, JSON.stringify(value));
      return true;
    } catch {
      return false;
    }
  },
};

/** Size a canvas to cssW x cssH CSS pixels (sharp on high-DPI screens), clear it to `background`;
 * its 2D context, drawing in CSS pixels. */
export function fitCanvas(canvas, cssW, cssH, background = "#10151c") {
  const dpr = window.devicePixelRatio || 1;
  if (canvas.width !== Math.round(cssW * dpr) || canvas.height !== Math.round(cssH * dpr)) {
    canvas.width = Math.round(cssW * dpr);
    canvas.height = Math.round(cssH * dpr);
    canvas.style.width = `${cssW}px`;
    canvas.style.height = `${cssH}px`;
  }
  const ctx = canvas.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  ctx.fillStyle = background;
  ctx.fillRect(0, 0, cssW, cssH);
  return ctx;
}

export const clone = (x) => (x === undefined ? undefined : JSON.parse(JSON.stringify(x)));

/** Offer a Blob as a file download. */
export function download(name, blob) {
  const url = URL.createObjectURL(blob);
  const a = h("a", { href: url, download: name });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
}
