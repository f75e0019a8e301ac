// Form controls for the fields students change most: the camera, the film size, the sampler, the
// integrator and depth, a chosen object's material K's and a chosen light. Each control writes its value
// back into the JSON text (SceneEditor.setField); the text stays the one source of truth.
import { $, $$, debounce, h } from "./util.js";

const num = (key, label, o = {}) => ({ key, label, type: "number", ...o });
const vec = (key, label, o = {}) => ({ key, label, type: "vec3", ...o });
const rgbf = (key, label, o = {}) => ({ key, label, type: "rgb", ...o });
const pick = (key, label, options, o = {}) => ({ key, label, type: "select", options, ...o });

const CAMERA = [
  vec("lookfrom", "lookfrom", { help: "where the eye is" }),
  vec("lookat", "lookat", { help: "the point looked at" }),
  vec("vup", "vup", { def: [0, 1, 0], help: "which way is up" }),
  num("vfov", "vfov (°)", { min: 1, max: 179, step: 1, help: "full vertical field of view" }),
  num("lens_radius", "lens radius", { min: 0, step: 0.01, def: 0, help: "0 = pinhole; more = shallower depth of field" }),
  num("focus_distance", "focus distance", { min: 0, step: 0.1, nullable: true, help: "empty = |lookat − lookfrom|" }),
];
const FILM = [num("width", "width (px)", { min: 1, step: 1 }), num("height", "height (px)", { min: 1, step: 1 })];
const SAMPLER = [
  pick("type", "sampler", ["center", "grid", "random", "jittered", "adaptive"], { def: "jittered" }),
  num("spp", "samples / pixel", { min: 1, step: 1, def: 16, help: "grid, jittered: a perfect square" }),
  num("threshold", "threshold", { min: 0, step: 0.01, def: 0.05, only: "adaptive" }),
  num("max_level", "max level", { min: 0, max: 6, step: 1, def: 3, only: "adaptive" }),
];
const RENDER = [
  pick("integrator", "integrator", ["whitted", "path", "radiosity"], { def: "whitted" }),
  num("max_depth", "max depth", { min: 1, max: 64, step: 1, def: 5, help: "1 = ray casting" }),
  num("light_samples", "light samples", { min: 1, step: 1, def: 1, help: "shadow rays per area light" }),
  num("min_weight", "min weight", { min: 0, step: 0.001, def: 0.001 }),
];
const MATERIAL = [
  rgbf("kd", "kd (diffuse)", { def: 0.5 }),
  rgbf("ks", "ks (specular)", { def: 0 }),
  num("shininess", "shininess n", { min: 0, step: 1, def: 32 }),
  rgbf("kr", "kr (reflection)", { def: 0 }),
  rgbf("kt", "kt (transmission)", { def: 0 }),
  num("ior", "ior", { min: 0.01, step: 0.01, def: 1.5 }),
  { key: "fresnel", label: "Fresnel", type: "check", def: false },
  num("gloss", "gloss m", { min: 0, step: 1, nullable: true, help: "empty = perfect mirror" }),
];
const LIGHT_FIELDS = {
  point: [vec("position", "position"), num("intensity", "intensity (W/sr)", { min: 0, step: 1 })],
  spot: [vec("position", "position"), vec("direction", "direction"), num("intensity", "intensity (W/sr)", { min: 0, step: 1 }), num("cutoff", "cutoff (°)", { min: 0, max: 90, step: 1 })],
  directional: [vec("direction", "direction"), num("irradiance", "irradiance (W/m²)", { min: 0, step: 0.1 })],
  quad: [vec("corner", "corner"), rgbf("radiance", "radiance")],
  disk: [vec("center", "center"), num("radius", "radius", { min: 0, step: 0.05 }), rgbf("radiance", "radiance")],
  sphere: [vec("center", "center"), num("radius", "radius", { min: 0, step: 0.05 }), rgbf("radiance", "radiance")],
};

let uid = 0;

/** "0.8" -> 0.8; "0.8, 0.1, 0.1" or "[0.8 0.1 0.1]" -> [0.8, 0.1, 0.1]; else undefined. */
function parseRGB(text) {
  const parts = text.replace(/[[\]]/g, " ").split(/[\s,]+/).filter(Boolean).map(Number);
  if (parts.length === 1 && Number.isFinite(parts[0])) return parts[0];
  if (parts.length === 3 && parts.every(Number.isFinite)) return parts;
  return undefined;
}
const showRGB = (v) => (Array.isArray(v) ? v.join(", ") : v === undefined || v === null ? "" : String(v));

export class SceneFields {
  constructor(form, editor) {
    this.form = form;
    this.editor = editor;
    this.value = null;
    this.objectIndex = 0;
    this.lightIndex = 0;
    this.sections = {};
    this.build();
  }

  build() {
    const section = (id, title, ...content) => {
      const body = h("div", { class: "fields-grid" });
      const fs = h("fieldset", { id: `fs-${id}` }, h("legend", {}, title), ...content, body);
      this.sections[id] = body;
      return fs;
    };
    this.objectSelect = h("select", { id: "field-object", "aria-label": "object whose material to edit" });
    this.objectSelect.addEventListener("change", () => {
      this.objectIndex = Number(this.objectSelect.value);
      this.refresh(this.value, true);
    });
    this.lightSelect = h("select", { id: "field-light", "aria-label": "light to edit" });
    this.lightSelect.addEventListener("change", () => {
      this.lightIndex = Number(this.lightSelect.value);
      this.refresh(this.value, true);
    });
    this.materialNote = h("p", { class: "note" });
    this.disabledNote = h("p", { class: "note warn", hidden: true }, "Fix the JSON syntax error first: the form reads and writes the text.");
    this.form.replaceChildren(
      this.disabledNote,
      section("camera", "Camera"),
      section("film", "Film"),
      section("sampler", "Sampler"),
      section("render", "Integrator and depth"),
      section("material", "Object's material", h("label", { class: "wide" }, "object ", this.objectSelect), this.materialNote),
      section("light", "Light", h("label", { class: "wide" }, "light ", this.lightSelect)),
    );
    this.form.addEventListener("submit", (e) => e.preventDefault());
  }

  /** A control for one field; `base` is the JSON path of the object holding `spec.key`. */
  control(spec, base, holder) {
    const id = `f${++uid}`;
    const path = [...base, spec.key];
    const current = holder ? holder[spec.key] : undefined;
    const value = current === undefined ? spec.def : current;
    const isDefault = current === undefined;
    const write = (v) => this.editor.setField(path, v);
    const wrap = (...els) =>
      h("div", { class: `field${spec.type === "vec3" ? " vec" : ""}${isDefault ? " is-default" : ""}`, dataset: { path: path.join(".") } }, ...els, spec.help ? h("small", { id: `${id}-help` }, spec.help) : null);
    const later = debounce(write, 350);
    if (spec.type === "number") {
      const input = h("input", { id, type: "number", step: spec.step ?? "any", min: spec.min, max: spec.max, value: value ?? "", placeholder: spec.nullable ? "auto" : "", "aria-describedby": spec.help ? `${id}-help` : null });
      input.addEventListener("input", () => {
        if (input.value === "" && spec.nullable) return later(null);
        const v = Number(input.value);
        if (input.value !== "" && Number.isFinite(v)) later(v);
      });
      return wrap(h("label", { for: id }, spec.label), input);
    }
    if (spec.type === "vec3") {
      const v = Array.isArray(value) ? value : ["", "", ""];
      const inputs = ["x", "y", "z"].map((axis, i) => h("input", { type: "number", step: "any", value: v[i] ?? "", "aria-label": `${spec.label} ${axis}`, id: i === 0 ? id : null }));
      for (const input of inputs)
        input.addEventListener("input", () => {
          const xs = inputs.map((x) => Number(x.value));
          if (inputs.every((x) => x.value !== "") && xs.every(Number.isFinite)) later(xs);
        });
      return wrap(h("label", { for: id }, spec.label), h("span", { class: "vec3" }, ...inputs));
    }
    if (spec.type === "rgb") {
      const input = h("input", { id, type: "text", inputmode: "decimal", value: showRGB(value), "aria-describedby": `${id}-help`, autocomplete: "off", spellcheck: "false" });
      input.addEventListener("input", () => {
        const v = parseRGB(input.value);
        input.setAttribute("aria-invalid", v === undefined ? "true" : "false");
        if (v !== undefined) later(v);
      });
      return wrap(h("label", { for: id }, spec.label), input, h("small", { id: `${id}-help` }, "a number, or r, g, b"));
    }
    if (spec.type === "select") {
      const select = h("select", { id }, spec.options.map((o) => h("option", { value: o, selected: o === value }, o)));
      select.addEventListener("change", () => write(select.value));
      return wrap(h("label", { for: id }, spec.label), select);
    }
    if (spec.type === "check") {
      const input = h("input", { id, type: "checkbox", checked: !!value });
      input.addEventListener("change", () => write(input.checked));
      return wrap(h("label", { for: id, class: "check" }, input, " ", spec.label));
    }
    return null;
  }

  fill(section, specs, base, holder, filter = () => true) {
    const body = this.sections[section];
    const shown = specs.filter(filter);
    const paths = shown.map((spec) => [...base, spec.key].join("."));
    const same = paths.join("\n") === $$(".field", body).map((el) => el.dataset.path).join("\n");
    if (same && body.contains(document.activeElement)) {
      // do not rebuild under the student's cursor: update the other controls' values only
      for (const el of $$(".field", body)) {
        const spec = shown[paths.indexOf(el.dataset.path)];
        const v = holder ? holder[spec.key] : undefined;
        for (const input of $$("input, select", el)) {
          if (input === document.activeElement) continue;
          if (spec.type === "vec3" && Array.isArray(v)) input.value = v[$$("input", el).indexOf(input)];
          else if (spec.type === "rgb" && v !== undefined) input.value = showRGB(v);
          else if (spec.type === "check") input.checked = !!v;
          else if (v !== undefined && v !== null) input.value = v;
        }
      }
      return;
    }
    // rebuild (the fields differ, e.g. another sampler type), keeping the focus on the same field
    const focused = body.contains(document.activeElement) ? document.activeElement.closest(".field")?.dataset.path : null;
    body.replaceChildren(...shown.map((spec) => this.control(spec, base, holder)));
    if (focused) $$(".field", body).find((el) => el.dataset.path === focused)?.querySelector("input, select")?.focus();
  }

  /** Follow the text: `value` is the parsed scene, or null when the JSON does not parse. */
  refresh(value, force = false) {
    const disabled = value === null || typeof value !== "object";
    this.disabledNote.hidden = !disabled;
    for (const fs of $$("fieldset", this.form)) fs.disabled = disabled;
    if (disabled) return;
    if (!force && this.value && JSON.stringify(this.value) === JSON.stringify(value)) return;
    this.value = value;
    const sec = (k) => (value[k] && typeof value[k] === "object" ? value[k] : {});
    this.fill("camera", CAMERA, ["camera"], sec("camera"));
    this.fill("film", FILM, ["film"], sec("film"));
    const sampler = sec("sampler");
    this.fill("sampler", SAMPLER, ["sampler"], sampler, (s) => !s.only || s.only === (sampler.type || "jittered"));
    this.fill("render", RENDER, ["render"], sec("render"));

    const objects = Array.isArray(value.objects) ? value.objects : [];
    this.objectIndex = Math.min(this.objectIndex, Math.max(0, objects.length - 1));
    const objectLabels = objects.map((o, i) => `${i}: ${(o && o.name) || (o && o.type) || "?"}`);
    if (objectLabels.join("\n") !== $$("option", this.objectSelect).map((o) => o.textContent).join("\n")) {
      this.objectSelect.replaceChildren(...objectLabels.map((l, i) => h("option", { value: i }, l)));
    }
    this.objectSelect.value = String(this.objectIndex);
    const obj = objects[this.objectIndex];
    if (obj && typeof obj.material === "string") {
      const users = objects.filter((o) => o && o.material === obj.material).length;
      const mats = value.materials && typeof value.materials === "object" ? value.materials : {};
      this.materialNote.textContent = `material "${obj.material}"${users > 1 ? `, shared by ${users} objects` : ""}`;
      this.fill("material", MATERIAL, ["materials", obj.material], mats[obj.material] || {});
    } else if (obj && obj.material && typeof obj.material === "object") {
      this.materialNote.textContent = "an inline material";
      this.fill("material", MATERIAL, ["objects", this.objectIndex, "material"], obj.material);
    } else {
      this.materialNote.textContent = objects.length ? "this object has no material yet" : "no objects";
      this.sections.material.replaceChildren();
    }

    const lights = Array.isArray(value.lights) ? value.lights : [];
    this.lightIndex = Math.min(this.lightIndex, Math.max(0, lights.length - 1));
    const lightLabels = lights.map((l, i) => `${i}: ${(l && l.type) || "?"}`);
    if (lightLabels.join("\n") !== $$("option", this.lightSelect).map((o) => o.textContent).join("\n")) {
      this.lightSelect.replaceChildren(...lightLabels.map((l, i) => h("option", { value: i }, l)));
    }
    this.lightSelect.value = String(this.lightIndex);
    const light = lights[this.lightIndex];
    this.fill("light", (light && LIGHT_FIELDS[light.type]) || [], ["lights", this.lightIndex], light || {});
  }

  /** Show the material of object `index` (the ray tree's "edit this material"). */
  selectObject(index) {
    if (!this.value) return;
    this.objectIndex = index;
    this.refresh(this.value, true);
    const fs = $("#fs-material", this.form);
    fs.closest("details")?.setAttribute("open", "");
    fs.scrollIntoView({ block: "nearest" });
    this.objectSelect.focus();
  }
}
