// The Build panel: a new scene from a template, objects, lights and materials added and removed, one object or
// light picked (in the 3D view, the rendered picture, or with keys) and moved or scaled with handles. Every
// change goes into the JSON text through the editor, as one step of its history (Undo takes it back); the text
// stays the one source of truth, and the panel follows it as the form does.
// Templates and material presets are static JSON files under web/templates/ (the presets are checked by
// tests/tracer/test_scene.py to give no warning).
import { request } from "./api.js";
import { BuildView } from "./buildview.js";
import { anchorOf, floorAndCeiling, freeSpot, itemAt, pickAt, r3, stage, v3 } from "./edits.js";
import { appendItem, formatJSON, removeAt, setValue } from "./jsonpos.js";
import { h } from "./util.js";
import { add, dot, length, mul, normalize, sub } from "./vec.js";

export const TEMPLATES = [
  { file: "empty_room", label: "Empty room (a camera and a light)" },
  { file: "cornell_box", label: "Cornell box (empty, with its area light)" },
  { file: "whitted", label: "Whitted's scene (mirror and glass balls)" },
];

const same = (a, b) => JSON.stringify(a) === JSON.stringify(b);

/** New objects, each placed from the scene's camera and floor (edits.js): {type: [label, make(scene, material)]}. */
const OBJECTS = {
  sphere: [
    "Sphere",
    (scene, material) => {
      const r = r3(0.5 * stage(scene).scale);
      return { type: "sphere", center: freeSpot(scene, r), radius: r, material };
    },
  ],
  plane: [
    "Floor (plane)",
    (scene, material) => {
      const { at, up, scale } = stage(scene);
      const height = dot(at, up) > 0 ? 0 : dot(at, up) - scale; // y = 0 under a camera looking down at the scene
      return {
        type: "plane",
        name: "floor",
        point: v3(add(at, mul(up, height - dot(at, up)))),
        normal: v3(up),
        material,
      };
    },
  ],
  box: [
    "Box",
    (scene, material) => {
      const s = 0.45 * stage(scene).scale;
      const c = freeSpot(scene, s * Math.sqrt(3)); // its corners reach that far
      c[1] = r3(c[1] - s * (Math.sqrt(3) - 1)); // and it stands on the floor
      return { type: "box", min: v3(sub(c, [s, s, s])), max: v3(add(c, [s, s, s])), material };
    },
  ],
  quad: [
    "Panel (quad)",
    (scene, material) => {
      const { right, up, scale } = stage(scene);
      const s = 0.5 * scale;
      const c = freeSpot(scene, s);
      return {
        type: "quad",
        corner: v3(sub(c, add(mul(right, s), mul(up, s)))),
        edge1: v3(mul(right, 2 * s)),
        edge2: v3(mul(up, 2 * s)),
        material,
      };
    },
  ],
};

/** Where a light over the scene goes: 4 scene units over the floor (or over what the camera looks at), out of
the picture above it, or just under the ceiling when there is one (a Cornell box's). */
function overhead(scene) {
  const { at, up, scale } = stage(scene);
  const { floor, ceiling } = floorAndCeiling(scene);
  const height = ceiling !== null ? ceiling - 0.02 * scale : (floor ?? dot(at, up)) + 4 * scale;
  return add(at, mul(up, height - dot(at, up)));
}

/** How far across a light reaches from its centre, along the floor (a point or spot light: 0). */
function lightReach(l) {
  if (l?.type === "quad" && Array.isArray(l.edge1) && Array.isArray(l.edge2))
    return Math.max(length(add(l.edge1, l.edge2)), length(sub(l.edge1, l.edge2))) / 2;
  return Number.isFinite(l?.radius) ? l.radius : 0;
}

/** Where a new area light of half-size `half` goes, so that it shadows nothing of the scene (a light with a size
 * blocks the shadow rays of the lights behind it: an area light added to the Empty room under its point light
 * cast a dark streak). {centre, k}: over the scene (`overhead`), raised above the lights already there when
 * there is no ceiling, grown by k so that it lights the floor as much from up there; under a ceiling, moved
 * aside of the lights there (a Cornell box's own). The message says where and why. */
function areaPlace(scene, half) {
  const { up, right, toward, scale } = stage(scene);
  const base = overhead(scene);
  const { ceiling } = floorAndCeiling(scene);
  const lights = (Array.isArray(scene.lights) ? scene.lights : []).map((l) => [l, anchorOf(l)]).filter(([, p]) => p);
  if (!lights.length) return { centre: base, k: 1, why: "" };
  if (ceiling === null) {
    const top = Math.max(...lights.map(([l, p]) => dot(p, up) + lightReach(l)));
    const lift = top + 0.5 * scale + half - dot(base, up);
    if (lift <= 0) return { centre: base, k: 1, why: "" };
    const k = (4 * scale + lift) / (4 * scale);
    return {
      centre: add(base, mul(up, lift)),
      k,
      why: ", above the scene's other lights (under them it would block their light: a shadow)",
    };
  }
  // under a ceiling: the middle, else the nearest spot aside (left, right, front, back) whose footprint on the
  // ceiling leaves every light's clear (their shadow rays go down from there)
  const extent = (l, axis) =>
    l.type === "quad" ? (Math.abs(dot(l.edge1, axis)) + Math.abs(dot(l.edge2, axis))) / 2 : lightReach(l);
  const margin = 0.05 * scale;
  const clear = (c) =>
    lights.every(
      ([l, p]) =>
        Math.abs(dot(sub(p, c), right)) >= extent(l, right) + half + margin ||
        Math.abs(dot(sub(p, c), toward)) >= extent(l, toward) + half + margin,
    );
  const aside = (axis) =>
    Math.max(...lights.map(([l, p]) => Math.abs(dot(sub(p, base), axis)) + extent(l, axis))) + half + margin;
  for (const [axis, side] of [
    [right, 0],
    [right, -1],
    [right, 1],
    [toward, -1],
    [toward, 1],
  ]) {
    const c = add(base, mul(axis, side * aside(axis)));
    if (clear(c))
      return {
        centre: c,
        k: 1,
        why: side ? ", beside the light under the ceiling (under it, it would block that light)" : "",
      };
  }
  return {
    centre: base,
    k: 1,
    why: ": under the light already there, it blocks that light's rays (its shadow is dark); move it aside with its handles",
  };
}

const LIGHTS = {
  point: [
    "Point light",
    (scene) => {
      const { right, scale } = stage(scene);
      return {
        type: "point",
        position: v3(add(overhead(scene), mul(right, 0.5 * scale))),
        intensity: r3(10 * scale * scale),
      };
    },
  ],
  spot: [
    "Spot light",
    (scene) => {
      const { at, right, up, toward, scale } = stage(scene);
      // over the scene to the left and a little lower, clear of an area light added overhead (which would block
      // its shadow rays), and inside a Cornell box's walls; aimed at what the camera looks at (its knob turns it)
      const aside = add(mul(right, -1.2 * scale), add(mul(toward, 0.6 * scale), mul(up, -0.15 * scale)));
      const position = v3(add(overhead(scene), aside));
      return {
        type: "spot",
        position,
        direction: v3(normalize(sub(at, position))),
        intensity: r3(20 * scale * scale),
        cutoff: 30,
        falloff: 2,
      };
    },
  ],
  quad: [
    "Area light (quad)",
    (scene) => {
      const { right, toward, scale } = stage(scene);
      const { centre, k, why } = areaPlace(scene, scale / 2);
      const s = scale * k;
      // edge1 x edge2 = right x toward points down: the light shines on the scene
      return [
        {
          type: "quad",
          corner: v3(sub(centre, mul(add(right, toward), s / 2))),
          edge1: v3(mul(right, s)),
          edge2: v3(mul(toward, s)),
          radiance: 16,
        },
        why,
      ];
    },
  ],
  sphere: [
    "Sphere light",
    (scene) => {
      const { up, scale } = stage(scene);
      const r = 0.2 * scale; // its whole ball under a ceiling
      const { centre, k, why } = areaPlace(scene, r);
      return [
        { type: "sphere", center: v3(sub(centre, mul(up, r * k + 0.02 * scale))), radius: r3(r * k), radiance: 120 },
        why,
      ];
    },
  ],
};

export class BuildPanel {
  /** root: the element to build into; editor: the SceneEditor; onPicked(of): the form shows the same object. */
  constructor(
    root,
    editor,
    { onPicked = () => {}, onLoad = (text, name) => editor.setText(text, name), notify = () => {} } = {},
  ) {
    this.root = root;
    this.onLoad = onLoad; // (text, name): a template replaces the text (main.js: as an example or a file does)
    this.editor = editor;
    this.onPicked = onPicked;
    this.notify = notify;
    this.value = null;
    this.picked = null;
    this.presets = {};
    this.build();
    request("GET", "templates/materials.json")
      .then((presets) => {
        this.presets = presets;
        this.fillMaterials();
      })
      .catch((err) => notify(`Could not load the material presets: ${err.message}.`, "warn"));
  }

  build() {
    const button = (label, run, attrs = {}) => h("button", { type: "button", onclick: run, ...attrs }, label);
    this.template = h(
      "select",
      { id: "build-template" },
      h("option", { value: "" }, "Start from…"),
      ...TEMPLATES.map((t) => h("option", { value: t.file }, t.label)),
    );
    this.template.addEventListener("change", () => this.newScene(this.template.value));
    this.material = h("select", { id: "build-material", "aria-describedby": "build-material-help" });
    this.material.addEventListener("change", () => (this.chosen = this.material.value));
    this.canvas = h("canvas", {
      id: "build-3d",
      tabindex: "0",
      role: "img",
      "aria-label":
        "3D view of the scene for building it: click a shape to pick it, drag its handles to move, scale or rotate it",
      "aria-describedby": "build-keys",
    });
    const box = h("div", { class: "canvas-box" }, this.canvas); // the view sizes itself to its box
    this.view = new BuildView(this.canvas, {
      onPick: (of) => this.pick(of),
      onEdit: (writes, what) => this.write(writes, what),
    });
    this.status = h(
      "p",
      { id: "build-status", role: "status", "aria-live": "polite" },
      "Nothing picked: click a shape in the 3D view or in the rendered picture.",
    );
    this.pickedMaterial = h("select", { id: "build-picked-material", disabled: true });
    this.pickedMaterial.addEventListener("change", () => this.setMaterial(this.pickedMaterial.value));
    this.removeButton = button("Remove", () => this.removePicked(), { id: "build-remove", disabled: true });
    this.preset = h("select", { id: "build-preset" });
    this.materials = h("select", { id: "build-materials" });
    this.root.replaceChildren(
      h("div", { class: "build-row" }, h("label", { class: "inline" }, "New scene ", this.template)),
      h(
        "div",
        { class: "build-row", role: "group", "aria-label": "Add an object" },
        h("span", { class: "build-head" }, "Add"),
        ...Object.entries(OBJECTS).map(([type, [label]]) =>
          button(label, () => this.addObject(type), { id: `build-add-${type}` }),
        ),
        h("label", { class: "inline" }, "with material ", this.material),
      ),
      h(
        "small",
        { id: "build-material-help", class: "hint" },
        "A preset (new) adds that material to the scene; the rest are the scene's own.",
      ),
      h(
        "div",
        { class: "build-row", role: "group", "aria-label": "Add a light" },
        h("span", { class: "build-head" }, "Light"),
        ...Object.entries(LIGHTS).map(([type, [label]]) =>
          button(label, () => this.addLight(type), { id: `build-light-${type}` }),
        ),
      ),
      h(
        "figure",
        { class: "build-fig" },
        box,
        h(
          "figcaption",
          { id: "build-keys", class: "hint" },
          "Drag an arrow to move along x (red), y (green) or z (blue), the square to move on the horizontal plane, the white knob to scale, the cyan knob sideways to rotate about the vertical, a spot light's orange knob to aim it; drag elsewhere to orbit. ",
          "Keys: N and L pick the next object and light, arrows move x and z, Page Up and Page Down move y, [ and ] scale, Q and E rotate 15°, A and D turn a spot or directional light, W and S tilt it, Shift+arrows orbit, Escape lets go. Ctrl+Z undoes.",
        ),
      ),
      this.status,
      h(
        "div",
        { class: "build-row", role: "group", "aria-label": "The picked object or light" },
        (this.pickedMaterialLabel = h("label", { class: "inline", hidden: true }, "material ", this.pickedMaterial)),
        this.removeButton,
      ),
      h(
        "div",
        { class: "build-row", role: "group", "aria-label": "Materials" },
        h("label", { class: "inline" }, "Add material ", this.preset),
        button("Add", () => this.addMaterial(this.preset.value), {
          id: "build-add-material",
          "aria-label": "Add the preset material",
        }),
        h("label", { class: "inline" }, "Remove material ", this.materials),
        button("Remove", () => this.removeMaterial(this.materials.value), {
          id: "build-remove-material",
          "aria-label": "Remove the chosen material",
        }),
      ),
    );
    // Ctrl+Z anywhere in the panel (the 3D view included) is the editor's undo
    this.root.addEventListener("keydown", (e) => {
      const key = e.key.toLowerCase();
      if (!(e.ctrlKey || e.metaKey) || e.altKey || (key !== "z" && key !== "y")) return;
      if (e.target.matches("input[type=text], input[type=number]")) return; // their own text's undo
      e.preventDefault();
      if (key === "y" || e.shiftKey) this.editor.redo();
      else this.editor.undo();
    });
  }

  /** Follow the text (the editor's parsed value, null while it does not parse). */
  refresh(value) {
    this.value = value && typeof value === "object" ? value : null;
    if (!this.value) return;
    if (this.picked && !itemAt(this.value, this.picked)) this.picked = null;
    this.fillMaterials();
    const film = { width: this.value.film?.width || 256, height: this.value.film?.height || 256 };
    this.view.update(this.value, film);
    this.view.setPicked(this.picked);
    this.showPicked();
  }

  names() {
    const m = this.value?.materials;
    return m && typeof m === "object" && !Array.isArray(m) ? Object.keys(m) : [];
  }

  /** The material menus: the scene's own, then the presets (each adds a new material). */
  fillMaterials() {
    const names = this.names();
    const presets = Object.entries(this.presets);
    const options = (keep) => [
      ...names.map((n) => h("option", { value: n, selected: n === keep }, n)),
      ...presets.map(([key, p]) =>
        h("option", { value: `preset:${key}`, selected: `preset:${key}` === keep }, `${p.label} (new)`),
      ),
    ];
    // the student's last choice while the scene has it, else the scene's first material, else a preset
    const chosen =
      this.chosen && (names.includes(this.chosen) || this.chosen.startsWith("preset:")) ? this.chosen : null;
    const keepMaterial = chosen || names[0] || "preset:diffuse";
    this.material.replaceChildren(...options(keepMaterial));
    const obj = this.picked?.[0] === "objects" ? itemAt(this.value, this.picked) : null;
    this.pickedMaterial.replaceChildren(
      ...(obj && typeof obj.material === "object" ? [h("option", { value: "", selected: true }, "(inline)")] : []),
      ...options(obj?.material),
    );
    this.preset.replaceChildren(...presets.map(([key, p]) => h("option", { value: key }, p.label)));
    const keep = this.materials.value;
    this.materials.replaceChildren(...names.map((n) => h("option", { value: n, selected: n === keep }, n)));
  }

  /** One change of the text (one step to undo): `change(text)` -> {text, start}. */
  change(change, what) {
    const ok = this.editor.edit(change, what);
    if (ok) this.refresh(this.editor.parseNow().value); // at once: the editor tells the others after a pause
    return ok;
  }

  write(writes, what) {
    const label = this.describe(this.picked);
    const ok = this.change(
      (text) => writes.reduce((r, [parts, v]) => setValue(r.text, parts, v), { text }),
      `${what} ${label}`,
    );
    if (ok)
      this.say(
        `${{ scale: "Scaled", aim: "Aimed", rotate: "Rotated" }[what] || "Moved"} ${label}: ${writes.map(([p, v]) => `${p.at(-1)} ${JSON.stringify(v)}`).join(", ")}.`,
      );
  }

  /** A material choice -> [the name to write, the preset's write to make first or null]. */
  materialFor(choice) {
    if (!choice.startsWith("preset:")) return [choice, null];
    const key = choice.slice(7);
    const preset = this.presets[key]?.material;
    const mats = this.value?.materials || {};
    let name = key;
    for (let n = 2; mats[name] && !same(mats[name], preset); n++) name = `${key}${n}`;
    return [name, mats[name] ? null : (text) => setValue(text, ["materials", name], preset)];
  }

  /** Start over from a template: the editor's whole text, one step (Undo brings the old scene back). */
  async newScene(file) {
    if (!file) return;
    // two templates chosen in a row may answer out of order: the editor gets the one chosen last
    const asked = (this.templateAsked = (this.templateAsked || 0) + 1);
    try {
      const scene = await request("GET", `templates/${file}.json`); // a static file of web/templates/
      if (asked !== this.templateAsked) return;
      this.picked = null;
      this.onLoad(formatJSON(scene), TEMPLATES.find((t) => t.file === file).label);
      this.say(`New scene: ${TEMPLATES.find((t) => t.file === file).label}. Undo brings the previous scene back.`);
    } catch (err) {
      if (asked === this.templateAsked) this.notify(`Could not load the template ${file}: ${err.message}.`);
    }
    this.template.value = "";
  }

  addObject(type) {
    if (!this.usable()) return;
    const [name, makeMaterial] = this.materialFor(this.material.value || "preset:diffuse");
    const obj = OBJECTS[type][1](this.value, name);
    const index = Array.isArray(this.value.objects) ? this.value.objects.length : 0;
    const ok = this.change(
      (text) => appendItem(makeMaterial ? makeMaterial(text).text : text, ["objects"], obj),
      `add a ${type}`,
    );
    if (!ok) return;
    this.chosen = this.material.value = name; // a preset is the scene's own material from now on: the next object gets the same
    this.pickAfter(["objects", index], `Added ${type} ${index} (material ${name}).`);
  }

  addLight(type) {
    if (!this.usable()) return;
    const made = LIGHTS[type][1](this.value);
    const [light, why] = Array.isArray(made) ? made : [made, ""]; // an area light: where it went, and why there
    const index = Array.isArray(this.value.lights) ? this.value.lights.length : 0;
    const area = type !== "point" && type !== "spot"; // lights with a size
    const samples = this.value.render?.light_samples;
    const ok = this.change((text) => {
      const r = appendItem(text, ["lights"], light);
      // an area light's soft shadow needs several shadow rays per point; one is the default
      return area && samples === undefined
        ? { text: setValue(r.text, ["render", "light_samples"], 16).text, start: r.start }
        : r;
    }, `add a ${type} light`);
    if (ok)
      this.pickAfter(
        ["lights", index],
        `Added light ${index} (${type})${why}${area && samples === undefined ? ", and render.light_samples 16 for its soft shadows" : ""}.`,
      );
  }

  addMaterial(key) {
    if (!this.usable() || !key) return;
    const [name, make] = this.materialFor(`preset:${key}`);
    if (!make) return this.say(`The scene has the material ${name} already.`);
    if (this.change(make, `add the material ${name}`))
      this.say(`Added the material ${name}: pick it for an object, or for the next one added.`);
    this.chosen = this.material.value = name;
  }

  removeMaterial(name) {
    if (!this.usable() || !name) return;
    const users = (this.value.objects || []).map((o, i) => (o?.material === name ? i : -1)).filter((i) => i >= 0);
    if (users.length)
      return this.say(
        `The material ${name} is used by object${users.length > 1 ? "s" : ""} ${users.join(", ")}: give ${users.length > 1 ? "them" : "it"} another material first.`,
        true,
      );
    if (this.change((text) => removeAt(text, ["materials", name]), `remove the material ${name}`))
      this.say(`Removed the material ${name}.`);
  }

  removePicked() {
    if (!this.usable() || !this.picked) return;
    const label = this.describe(this.picked);
    const of = this.picked;
    this.picked = null;
    if (this.change((text) => removeAt(text, of), `remove ${label}`))
      this.say(`Removed ${label}. Undo brings it back.`);
  }

  setMaterial(choice) {
    if (!this.usable() || this.picked?.[0] !== "objects" || !choice) return;
    const [name, make] = this.materialFor(choice);
    const ok = this.change(
      (text) => setValue(make ? make(text).text : text, [...this.picked, "material"], name),
      `set the material of ${this.describe(this.picked)}`,
    );
    if (ok) this.say(`${this.describe(this.picked)} now has the material ${name}.`);
  }

  usable() {
    if (this.value) return true;
    this.say("The JSON does not parse: fix it first (the problem list says where).", true);
    return false;
  }

  // -- picking ------------------------------------------------------------------------------------

  pick(of) {
    this.picked = of && itemAt(this.value, of) ? of : null;
    this.view.setPicked(this.picked);
    this.fillMaterials();
    this.showPicked(true);
    if (this.picked) this.onPicked(this.picked);
  }

  /** After an add: pick the new one once the text has it (the editor's change reaches refresh first). */
  pickAfter(of, message) {
    this.pick(of);
    this.say(message);
  }

  /** The rendered picture was clicked at pixel (x, y) of a width x height image: pick what its eye ray meets. */
  pickPixel(x, y, width, height) {
    if (!this.value?.camera) return null;
    let found = null;
    try {
      found = pickAt(this.value, x + 0.5, y + 0.5, width, height);
    } catch {
      found = null; // a camera being typed
    }
    this.pick(found?.of || null);
    if (!found) this.say(`Nothing at pixel (${x}, ${y}): the eye ray leaves the scene.`);
    return found;
  }

  /** The pixel's ray tree came back from the server (for the scene in the editor): a mesh read from a file, whose
   * triangles the page does not have, is picked from its eye ray's hit when it is nearer than what the page met
   * (`found`: pickPixel's answer). */
  pickFromTree(tree, found) {
    const eye = tree?.nodes?.find((n) => n.parent === null || n.parent === undefined);
    const i = eye?.hit?.object;
    const o = Number.isInteger(i) ? this.value?.objects?.[i] : null;
    if (o?.type !== "mesh" || !o.file || (found && !(eye.t < found.t))) return;
    this.pick(["objects", i]);
  }

  describe(of) {
    const item = itemAt(this.value, of);
    if (!item) return "";
    const kind = of[0] === "objects" ? "object" : "light";
    return `${kind} ${of[1]} (${item.name ? `${item.name}, ` : ""}${item.type})`;
  }

  showPicked(announce = false) {
    const item = itemAt(this.value, this.picked);
    this.removeButton.disabled = !item;
    this.removeButton.textContent = item
      ? `Remove ${this.picked[0] === "objects" ? "object" : "light"} ${this.picked[1]}`
      : "Remove";
    this.pickedMaterial.disabled = !item || this.picked[0] !== "objects";
    this.pickedMaterialLabel.hidden = this.pickedMaterial.disabled; // a light has no material
    this.root.dataset.picked = item ? this.picked.join(".") : "";
    if (announce)
      this.say(
        item
          ? `Picked ${this.describe(this.picked)}.`
          : "Nothing picked: click a shape in the 3D view or in the rendered picture.",
      );
  }

  /** An undo or redo of the editor (any step: the panel's, the form's, typing): the status names the step as
   * undone or redone, never as done (it would still say "Moved object 0" after the move was undone). */
  travelled(kind, what) {
    const step = what || "the last change";
    this.say(kind === "undo" ? `Undid: ${step}. Redo does it again.` : `Redid: ${step}.`);
  }

  say(text, bad = false) {
    this.status.textContent = text;
    this.status.dataset.kind = bad ? "warn" : "ok";
  }
}
