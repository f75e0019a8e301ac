// The ray tree of one pixel sample, shown four ways and linked: the diagram, the rays over the image,
// the 3D view, and the tree in words (a list a screen reader follows and the keyboard walks: raylist.js). Hovering (or focusing) a ray anywhere highlights it everywhere and shows its numbers;
// a click keeps it. The depth slider replays the tree one generation of rays at a time.
import { api } from "./api.js";
import { renderDiagram } from "./diagram.js";
import { Overlay } from "./overlay.js";
import { renderRayList } from "./raylist.js";
import { RAY_STYLES, countRays, endWords, legend, styleKey } from "./rays.js";
import { drawRays, highlightRay, treeModel } from "./rayviews.js";
import { withDefaults } from "./schema.js";
import { $, cssColour, h, num, rgb } from "./util.js";
import { View3D } from "./view3d.js";

/** Sample indices a pixel has: the adaptive sampler's grid points, else spp (the schema's defaults fill in
 * what the scene leaves out). */
export function sampleCount(scene) {
  const sp = withDefaults("sampler", scene.sampler);
  if (sp.type === "adaptive") {
    const g = 2 ** (sp.max_level + 1);
    return { count: (g + 1) * (g + 1), centre: (g / 2) * (g + 1) + g / 2, grid: g };
  }
  return { count: sp.spp, centre: 0 };
}

export class RayTreePanel {
  constructor({ onPick, onEditObject }) {
    this.onPick = onPick; // (x, y): another pixel of the same image
    this.onEditObject = onEditObject; // (objectIndex)
    this.el = {
      section: $("#raytree"),
      pixel: $("#rt-pixel"),
      sample: $("#rt-sample"),
      sampleOf: $("#rt-sample-of"),
      depth: $("#rt-depth"),
      depthOut: $("#rt-depth-out"),
      play: $("#rt-play"),
      fit: $("#rt-fit"),
      status: $("#rt-status"),
      details: $("#rt-details"),
      diagram: $("#rt-diagram"),
      list: $("#rt-list"),
      overlayCanvas: $("#rt-overlay"),
      body: $("#rt-body"),
      swatch: $("#rt-colour"),
    };
    $("#rt-legend").replaceWith(legend());
    this.overlay = new Overlay($("#rt-overlay"), {
      onHover: (id) => this.hover(id),
      onSelect: (id) => this.select(id),
      onPick: (x, y) => this.onPick(x, y),
    });
    this.view3d = new View3D($("#rt-3d"), { onHover: (id) => this.hover(id), onSelect: (id) => this.select(id) });
    this.model = null;
    this.hovered = null;
    this.selected = null;
    this.seq = 0;
    this.el.depth.addEventListener("input", () => this.setDepth(Number(this.el.depth.value)));
    this.el.play.addEventListener("click", () => this.replay());
    this.el.sample.addEventListener("change", () => this.reload());
    // a phone: the boxes at their own size, scrolled (fitted into 360 px, a tree's words are too small to read)
    if (window.matchMedia("(max-width: 820px)").matches) this.el.fit.setAttribute("aria-pressed", "false");
    window.addEventListener(
      "resize",
      () => this.el.fit.getAttribute("aria-pressed") === "true" && this.diagram?.fit(true),
    );
    this.el.fit.addEventListener("click", () => {
      const on = this.el.fit.getAttribute("aria-pressed") !== "true";
      this.el.fit.setAttribute("aria-pressed", String(on));
      this.diagram?.fit(on);
    });
  }

  /** view: the viewer's {id, scene, sceneText, width, height}; imageUrl: what the overlay draws on. The tree
   * shown, or null (an error, or a later click came first). */
  async show(view, imageUrl, x, y, sample = null) {
    const { count, centre } = sampleCount(view.scene);
    if (sample === null)
      sample =
        this.request && this.request.view.id === view.id
          ? Math.min(Number(this.el.sample.value) || 0, count - 1)
          : centre;
    this.request = { view, imageUrl, x, y, sample };
    this.el.section.hidden = false;
    this.el.sample.max = String(count - 1);
    this.el.sample.value = String(sample);
    this.el.sampleOf.textContent = `of 0…${count - 1}${view.scene.sampler?.type === "adaptive" ? " (adaptive: a grid point; the centre is the default)" : ""}`;
    this.el.pixel.textContent = `pixel (${x}, ${y})`;
    this.status("busy", `Tracing the rays of pixel (${x}, ${y}), sample ${sample}…`);
    const seq = ++this.seq;
    let tree;
    try {
      tree = await api.raytree(view.sceneText, x, y, sample);
    } catch (err) {
      if (seq === this.seq) this.status("error", `Could not get the ray tree: ${err.message}.`);
      return null;
    }
    if (seq !== this.seq) return null;
    this.present(tree, view, imageUrl);
    return tree;
  }

  reload() {
    if (!this.request) return;
    const { view, imageUrl, x, y } = this.request;
    const sample = Math.max(0, Math.floor(Number(this.el.sample.value) || 0));
    this.show(view, imageUrl, x, y, sample);
  }

  present(tree, view, imageUrl) {
    const model = treeModel(tree);
    const { nodes, maxDepth } = model;
    this.model = model;
    this.hovered = this.selected = this.focused = null;
    const kinds = {};
    for (const n of nodes) kinds[styleKey(n)] = (kinds[styleKey(n)] || 0) + 1;
    const counts = Object.entries(kinds)
      .map(([k, c]) => countRays(k, c))
      .join(", ");
    this.el.swatch.style.background = cssColour(tree.color);
    this.el.swatch.title = `pixel sample colour ${rgb(tree.color)}`;
    this.status(
      "ok",
      `${nodes.length} rays (${counts}). Sample colour ${rgb(tree.color)}${tree.filter_weight !== undefined && tree.filter_weight !== 1 ? ` × filter weight ${num(tree.filter_weight)}` : ""}${tree.time !== undefined ? `, time ${num(tree.time)}` : ""}.${tree.truncated ? " The tree was cut at 8192 rays." : ""}`,
    );
    this.el.body.hidden = false;
    const where = `pixel (${tree.pixel[0]}, ${tree.pixel[1]}), sample ${tree.sample}`;
    this.diagram = renderDiagram(this.el.diagram, model, {
      onHover: (id) => this.hover(id, false),
      onSelect: (id) => this.select(id),
      label: `ray tree diagram of ${where}: ${nodes.length} rays (the tree in words, below, names each)`,
    });
    this.list = renderRayList(this.el.list, model, {
      label: `The ${nodes.length} rays of ${where}`,
      onFocus: (id) => this.focusRay(id),
      onSelect: (id) => this.select(id),
    });
    this.el.overlayCanvas.setAttribute(
      "aria-label",
      `the ${nodes.length} rays of ${where} drawn over the rendered image`,
    );
    this.diagram.fit(this.el.fit.getAttribute("aria-pressed") === "true");
    drawRays(this.overlay, this.view3d, imageUrl, model, view);
    this.el.depth.min = "1";
    this.el.depth.max = String(maxDepth);
    this.el.depth.value = String(maxDepth);
    this.el.depth.disabled = maxDepth <= 1;
    this.el.play.disabled = maxDepth <= 1;
    this.setDepth(maxDepth);
    this.details(null);
  }

  status(kind, text) {
    this.el.status.dataset.kind = kind;
    this.el.status.textContent = text;
  }

  setDepth(d) {
    if (!this.model) return;
    this.depth = d;
    const shown = this.model.nodes.filter((n) => n.depth <= d).length;
    this.el.depthOut.textContent = `depth ≤ ${d} of ${this.model.maxDepth}: ${shown} of ${this.model.nodes.length} rays`;
    this.diagram.setDepth(d);
    this.list.setDepth(d);
    this.overlay.setDepth(d);
    this.view3d.setDepth(d);
  }

  replay() {
    if (this.timer) {
      clearInterval(this.timer);
      this.timer = null;
      this.el.play.textContent = "▶ Replay";
      return;
    }
    let d = 1;
    this.el.depth.value = "1";
    this.setDepth(1);
    this.el.play.textContent = "■ Stop";
    this.timer = setInterval(() => {
      d++;
      if (!this.model || d > this.model.maxDepth) {
        clearInterval(this.timer);
        this.timer = null;
        this.el.play.textContent = "▶ Replay";
        return;
      }
      this.el.depth.value = String(d);
      this.setDepth(d);
    }, 900);
  }

  hover(id, scroll = true) {
    if (id === this.hovered) return;
    this.hovered = id;
    this.link(scroll);
  }

  /** The ray the keyboard is on in the tree in words (null: the list lost the focus): it wins over the mouse's
   * hover, which a box scrolled under a resting pointer would otherwise take. */
  focusRay(id) {
    if (id === this.focused) return;
    this.focused = id;
    this.link(true);
  }

  select(id) {
    this.selected = this.selected === id ? null : id;
    this.link(true);
  }

  link(scroll) {
    const id = this.focused ?? this.hovered ?? this.selected;
    highlightRay(this, id, scroll && (this.focused ?? this.hovered) !== null);
    this.list.select(this.selected);
    this.details(id);
  }

  /** The numbers of one ray (or, with none chosen, a hint and the root's). */
  details(id) {
    const box = this.el.details;
    if (!this.model) return;
    const n = this.model.byId.get(id ?? this.model.root.id);
    const st = RAY_STYLES[styleKey(n)];
    const rows = [];
    const row = (k, v, swatch = null) =>
      rows.push(
        h("dt", {}, k),
        h("dd", {}, swatch ? h("span", { class: "sw", style: `background:${cssColour(swatch)}` }) : null, v),
      );
    const v3 = (v) => (v ? v.map((x) => num(x, 3)).join(", ") : "–");
    row(
      "ray",
      `#${n.id} ${n.kind}, depth ${n.depth}${n.parent !== null && n.parent !== undefined ? `, child of #${n.parent}` : ""}`,
    );
    if (n.kind === "shadow") {
      row(
        "towards",
        `light ${n.light}${this.request?.view.scene.lights?.[n.light] ? ` (${this.request.view.scene.lights[n.light].type})` : ""}`,
      );
      row(
        "result",
        n.occluded ? `blocked by ${n.hit?.object_name || "an object"} at t = ${num(n.t)}` : "reached the light",
      );
      row("radiance", `${rgb(n.radiance)} (f_att · I · cosθ · f at the parent's hit; 0 when blocked)`, n.radiance);
    } else {
      if (n.hit) {
        row(
          "hit",
          `${n.hit.object_name || (n.hit.light !== null && n.hit.light !== undefined ? `light ${n.hit.light}` : `object ${n.hit.object}`)} at t = ${num(n.t)}${n.hit.front_face === false ? " (back face)" : ""}`,
        );
        row("material", n.hit.material ?? "–");
      } else row("hit", "nothing: the ray left the scene");
      row("k", rgb(n.k ?? [1, 1, 1]), null);
      row("weight", `${rgb(n.weight)} (product of the K's from the eye)`, n.weight);
      if (n.terms) {
        const t = n.terms;
        row("ambient", `${rgb(t.ambient)} = ka · Ia`, t.ambient);
        row("diffuse", `${rgb(t.diffuse)} = Σ f_att · I · kd/π · cosθ`, t.diffuse);
        row("specular", `${rgb(t.specular)} = Σ f_att · I · ks (n+2)/2π cosⁿα · cosθ`, t.specular);
        if (t.emission?.some((x) => x)) row("emission", rgb(t.emission), t.emission);
      }
      row("radiance", `${rgb(n.radiance)} carried back (local terms + weighted children)`, n.radiance);
      if (n.fog_transmittance !== null && n.fog_transmittance !== undefined)
        row("fog", `transmittance e^(−density·t) = ${rgb(n.fog_transmittance)}`);
    }
    row("ended", endWords(n));
    row("origin", v3(n.origin));
    row("direction", v3(n.direction));
    if (n.hit) {
      row("hit point", v3(n.hit.point));
      row("normal", v3(n.hit.normal));
    }
    const edit =
      n.hit && Number.isInteger(n.hit.object) && this.onEditObject
        ? h(
            "button",
            { type: "button", class: "small", onclick: () => this.onEditObject(n.hit.object) },
            `Edit the material of ${n.hit.object_name || `object ${n.hit.object}`}`,
          )
        : null;
    box.replaceChildren(
      h(
        "h3",
        {},
        h("span", { class: "kind-dot", style: `background:${st.colour}` }),
        id === null ? "The eye ray (hover a ray for its numbers)" : `Ray #${n.id}`,
      ),
      h("dl", {}, rows),
      edit,
    );
  }
}
