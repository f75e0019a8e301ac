// Looking closely at pictures side by side (a lesson's panels): a magnifier that shows the same pixels of every
// picture of the group at once, each pixel a square (nearest neighbour, never smoothed), and a full-size view
// of the group, zoomable x1 to x8. Mouse: hover or drag a picture to move the lenses, click for the full-size
// view. Keyboard: focus a picture, arrows move the lenses one pixel (Shift: 10), Enter opens the full-size view,
// Escape hides the lenses or closes the view; on a picture with a click of its own, Space clicks at the lenses. A picture with a click of its own (class "clickable": the depth of
// field lesson draws on the pictures) hides the lenses when clicked, until the pointer leaves it, so that they do
// not cover what the click drew.
import { h } from "./util.js";

const LENS = 120; // CSS pixels of a lens
const ZOOM = 8; // picture pixels -> lens pixels
const ZOOMS = [1, 2, 4, 8];

/** Make the pictures (`selector`) inside `container` one group to inspect; pictures added later join it.
 * `labelOf(img)` names a picture in the full-size view (default: its alt text). */
export function inspectGroup(container, selector, { labelOf = (img) => img.alt } = {}) {
  let at = null; // the lenses' centre, in picture pixels of the picture under the pointer: [x, y] (fractional)
  let clicked = null; // a clickable picture just clicked: no lenses while the pointer stays on it
  const shown = () =>
    [...container.querySelectorAll(selector)].filter((i) => !i.hidden && i.complete && i.naturalWidth > 0);

  const prepare = () => {
    for (const img of container.querySelectorAll(selector)) {
      if (img.dataset.inspect) continue;
      img.dataset.inspect = "true";
      img.tabIndex = 0;
      img.classList.add("inspectable");
      img.title = img.classList.contains("clickable")
        ? "Hover to magnify every picture here at the same place; double-click (or Enter) for the full size; with the keyboard, Space clicks where the lens is"
        : "Hover to magnify every picture here at the same place; click (or Enter) for the full size";
      img.addEventListener("load", () => at && draw());
    }
  };
  prepare();
  new MutationObserver(prepare).observe(container, { childList: true, subtree: true });

  /** The lenses: one per picture, at the same place of each, drawn pixel for pixel. */
  function draw() {
    for (const img of container.querySelectorAll(selector)) {
      const lens = lensOf(img);
      if (!at || img.hidden || !img.complete || !img.naturalWidth) {
        lens.hidden = true;
        continue;
      }
      const [u, v] = at;
      const n = LENS / ZOOM; // picture pixels across a lens
      const px = Math.min(img.naturalWidth - 1, Math.max(0, Math.floor(u * img.naturalWidth)));
      const py = Math.min(img.naturalHeight - 1, Math.max(0, Math.floor(v * img.naturalHeight)));
      const sx = px + 0.5 - n / 2;
      const sy = py + 0.5 - n / 2;
      const ctx = lens.getContext("2d");
      ctx.imageSmoothingEnabled = false;
      ctx.fillStyle = "#10151c";
      ctx.fillRect(0, 0, LENS, LENS);
      ctx.drawImage(img, sx, sy, n, n, 0, 0, LENS, LENS);
      ctx.strokeStyle = "rgba(255, 255, 255, 0.85)"; // the pixel under the pointer
      ctx.strokeRect((px - sx) * ZOOM + 0.5, (py - sy) * ZOOM + 0.5, ZOOM - 1, ZOOM - 1);
      lens.dataset.pixel = `${px},${py}`;
      lens.hidden = false;
      const c = contentBox(img);
      const left = img.offsetLeft + c.left + u * c.width - LENS / 2;
      const top = img.offsetTop + c.top + v * c.height - LENS / 2;
      lens.style.left = `${Math.round(left)}px`; // through the CSSOM: the page's content security policy forbids style attributes
      lens.style.top = `${Math.round(top)}px`;
    }
  }

  function hide() {
    at = null;
    draw();
  }

  const moveTo = (img, e) => {
    const r = img.getBoundingClientRect();
    const c = contentBox(img);
    at = [(e.clientX - r.left - c.left) / c.width, (e.clientY - r.top - c.top) / c.height];
    draw();
  };
  container.addEventListener("pointermove", (e) => {
    const img = e.target.closest?.(selector);
    if (img !== clicked) clicked = null;
    if (img && container.contains(img) && !clicked) moveTo(img, e);
    else if (at) hide();
  });
  container.addEventListener("pointerleave", () => {
    clicked = null;
    hide();
  });
  container.addEventListener("click", (e) => {
    const img = e.target.closest?.(selector);
    if (!img || !container.contains(img)) return;
    if (!img.classList.contains("clickable")) openFull(shown(), img, labelOf);
    else {
      clicked = img; // a click of its own, which may draw under the lenses
      hide();
    }
  });
  container.addEventListener("dblclick", (e) => {
    const img = e.target.closest?.(selector);
    if (img && container.contains(img) && img.classList.contains("clickable")) openFull(shown(), img, labelOf);
  });
  container.addEventListener("keydown", (e) => {
    const img = e.target.closest?.(selector);
    if (!img || !container.contains(img) || !img.naturalWidth) return;
    const step = e.shiftKey ? 10 : 1;
    const d = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step] }[e.key];
    if (d) {
      e.preventDefault();
      clicked = null;
      const [u, v] = at || [0.5, 0.5];
      const x = Math.min(img.naturalWidth - 1, Math.max(0, Math.floor(u * img.naturalWidth) + d[0]));
      const y = Math.min(img.naturalHeight - 1, Math.max(0, Math.floor(v * img.naturalHeight) + d[1]));
      at = [(x + 0.5) / img.naturalWidth, (y + 0.5) / img.naturalHeight];
      draw();
    } else if (e.key === " " && img.classList.contains("clickable")) {
      e.preventDefault(); // the picture's own click, at the lenses' pixel (WCAG 2.1.1: what the mouse does, the keys do)
      const kept = at || [0.5, 0.5];
      const r = img.getBoundingClientRect();
      const c = contentBox(img);
      img.dispatchEvent(
        new MouseEvent("click", {
          bubbles: true,
          clientX: r.left + c.left + kept[0] * c.width,
          clientY: r.top + c.top + kept[1] * c.height,
        }),
      );
      at = kept; // the lenses hide (the click draws under them); the next arrow goes on from here
    } else if (e.key === "Enter" || e.key === " ") {
      e.preventDefault();
      openFull(shown(), img, labelOf);
    } else if (e.key === "Escape") hide();
  });
  container.addEventListener("focusout", (e) => {
    if (!container.contains(e.relatedTarget)) hide();
  });
  return { draw, hide };
}

/** Where the picture is drawn inside its element (`object-fit: contain` centres it): CSS pixels. */
function contentBox(img) {
  const w = img.clientWidth || 1;
  const hh = img.clientHeight || 1;
  if (getComputedStyle(img).objectFit !== "contain" || !img.naturalWidth)
    return { left: 0, top: 0, width: w, height: hh };
  const k = Math.min(w / img.naturalWidth, hh / img.naturalHeight);
  const width = img.naturalWidth * k;
  const height = img.naturalHeight * k;
  return { left: (w - width) / 2, top: (hh - height) / 2, width, height };
}

function lensOf(img) {
  let lens = img.inspectLens;
  if (!lens || lens.parentElement !== img.parentElement) {
    lens = h("canvas", { class: "inspect-lens", width: LENS, height: LENS, "aria-hidden": "true", hidden: true });
    img.after(lens);
    img.inspectLens = lens;
  }
  return lens;
}

let dialog = null;

/** The full-size view: the group's pictures side by side at x1..x8, their scrolling kept together. */
function openFull(images, chosen, labelOf) {
  if (!images.length) return;
  dialog?.remove();
  const zoomOut = h("output", { class: "inspect-zoom-out" });
  const zoom = h("input", {
    type: "range",
    min: 0,
    max: ZOOMS.length - 1,
    step: 1,
    value: 2,
    "aria-label": "zoom",
    class: "inspect-zoom",
  });
  const close = h(
    "button",
    { type: "button", class: "small", "aria-label": "Close the full-size view" },
    "Close (Esc)",
  );
  const boxes = images.map((img) =>
    h(
      "figure",
      { class: "inspect-figure" },
      h(
        "div",
        { class: "inspect-scroll" },
        h("img", {
          src: img.currentSrc || img.src,
          alt: img.alt,
          class: "inspect-full-img",
          dataset: { natural: `${img.naturalWidth}x${img.naturalHeight}` },
        }),
      ),
      h("figcaption", {}, labelOf(img) || ""),
    ),
  );
  dialog = h(
    "dialog",
    { class: "inspect-dialog", "aria-label": "The pictures at full size" },
    h(
      "div",
      { class: "inspect-head" },
      h("strong", {}, "Full size"),
      h("label", { class: "inline" }, "zoom ", zoom),
      zoomOut,
      h("span", { class: "hint" }, "each picture pixel a square; scrolling one scrolls all"),
      close,
    ),
    h("div", { class: "inspect-row", dataset: { count: images.length } }, ...boxes),
  );
  document.body.append(dialog);
  const setZoom = () => {
    const k = ZOOMS[Number(zoom.value)];
    zoomOut.textContent = `×${k}`;
    dialog.dataset.zoom = String(k);
    for (const [i, box] of boxes.entries()) {
      const full = box.querySelector("img");
      full.style.width = `${images[i].naturalWidth * k}px`;
      full.style.height = `${images[i].naturalHeight * k}px`;
    }
  };
  zoom.addEventListener("input", setZoom);
  setZoom();
  let syncing = false;
  const scrolls = boxes.map((b) => b.querySelector(".inspect-scroll"));
  for (const s of scrolls)
    s.addEventListener("scroll", () => {
      if (syncing) return;
      syncing = true;
      for (const o of scrolls) if (o !== s) o.scrollTo(s.scrollLeft, s.scrollTop);
      requestAnimationFrame(() => (syncing = false));
    });
  const d = dialog;
  close.addEventListener("click", () => d.close());
  d.addEventListener("close", () => {
    d.remove();
    chosen.focus();
  });
  d.showModal();
  zoom.focus();
}
