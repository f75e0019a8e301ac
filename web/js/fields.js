// Form controls for the fields students change most: the camera, the film size, the sampler, the
// integrator and depth, a chosen object's material K's and a chosen light. Each control writes its value
// back into the JSON text (SceneEditor.setField); the text stays the one source of truth.
// Only labels, their order, the spinners' steps and short hints live here: each field's kind, bounds,
// default and choices come from the server's schema (schema.js).
import { defaultOf, part, rule, withDefaults } from "./schema.js";
import { $, $$, debounce, h } from "./util.js";

/** A field of the form: its key in the scene, its label; `step`: the spinner's step for a number that is not
 * an integer; `help`: a hint under it; `only`: shown for that sampler type alone. */
const f = (key, label, o = {}) => ({ key, label, ...o });

const CAMERA = [
  f("lookfrom", "lookfrom", { help: "where the eye is" }),
  f("lookat", "lookat", { help: "the point looked at" }),
  f("vup", "vup", { help: "which way is up" }),
  f("vfov", "vfov (°)", { step: 1, help: "full vertical field of view" }),
  f("lens_radius", "lens radius", { step: 0.01, help: "0 = pinhole; more = shallower depth of field" }),
  f("focus_distance", "focus distance", { step: 0.1, help: "empty = |lookat − lookfrom|" }),
];
const FILM = [f("width", "width (px)"), f("height", "height (px)")];
const SAMPLER = [
  f("type", "sampler"),
  f("spp", "samples / pixel", { help: "grid, jittered: a perfect square" }),
  f("threshold", "threshold", { step: 0.01, only: "adaptive" }),
  f("max_level", "max level", { only: "adaptive" }),
];
const RENDER = [
  f("integrator", "integrator"),
  f("max_depth", "max depth", { help: "1 = ray casting" }),
  f("light_samples", "light samples", { help: "shadow rays per area light" }),
  f("min_weight", "min weight", { step: 0.001 }),
];
const MATERIAL = [
  f("kd", "kd (diffuse)"),
  f("ks", "ks (specular)"),
  f("shininess", "shininess n", { step: 1 }),
  f("kr", "kr (reflection)"),
  f("kt", "kt (transmission)"),
  f("ior", "ior", { step: 0.01 }),
  f("fresnel", "Fresnel"),
  f("gloss", "gloss m", { step: 1, help: "empty = perfect mirror" }),
];
const LIGHT_FIELDS = {
  point: [f("position", "position"), f("intensity", "intensity (W/sr)", { step: 1 })],
  spot: [
    f("position", "position"),
    f("direction", "direction"),
    f("intensity", "intensity (W/sr)", { step: 1 }),
    f("cutoff", "cutoff (°)", { step: 1 }),
  ],
  directional: [f("direction", "direction"), f("irradiance", "irradiance (W/m²)", { step: 0.1 })],
  quad: [f("corner", "corner"), f("radiance", "radiance")],
  disk: [f("center", "center"), f("radius", "radius", { step: 0.05 }), f("radiance", "radiance")],
  sphere: [f("center", "center"), f("radius", "radius", { step: 0.05 }), f("radiance", "radiance")],
};

/** Without the schema (the server not answering): the kind the text's value shows. */
function kindOfValue(v) {
  if (Array.isArray(v)) return "vec3";
  if (typeof v === "boolean") return "check";
  if (typeof v === "string") return "select";
  return "number";
}

/** The input's min and max: the schema's bounds; an exclusive bound moved in by one step, the nearest
 * value the spinner reaches (vfov: 0 < v < 180 with step 1 gives 1..179; a step of "any": the bound). */
function inputBounds(r, step) {
  const by = typeof step === "number" ? step : 0;
  return {
    min: r?.min ?? (r?.exclusiveMin !== undefined ? r.exclusiveMin + by : undefined),
    max: r?.max ?? (r?.exclusiveMax !== undefined ? r.exclusiveMax - by : undefined),
  };
}

let uid = 0;

/** "0.8" -> 0.8; "0.8, 0.1, 0.1" or "[0.8 0.1 0.1]" -> [0.8, 0.1, 0.1]; else undefined. */
function parseRGB(text) {
  const parts = text
    .replace(/[[\]]/g, " ")
    .split(/[\s,]+/)
    .filter(Boolean)
    .map(Number);
  if (parts.length === 1 && Number.isFinite(parts[0])) return parts[0];
  if (parts.length === 3 && parts.every(Number.isFinite)) return parts;
  return undefined;
}
/** An RGB value as text; a default of three equal numbers as the one number it means (kd 0.5). */
function showRGB(v, isDefault = false) {
  if (Array.isArray(v)) return isDefault && v.every((x) => x === v[0]) ? String(v[0]) : v.join(", ");
  return v === undefined || v === null ? "" : String(v);
}

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
    this.disabledNote = h(
      "p",
      { class: "note warn", id: "form-stale-note", hidden: true },
      "The JSON has a syntax error, so the form is blank: it reads and writes the text, and follows it again once the text parses.",
    );
    this.form.replaceChildren(
      this.disabledNote,
      section("camera", "Camera"),
      section("film", "Film"),
      section("sampler", "Sampler"),
      section("render", "Integrator and depth"),
      section(
        "material",
        "Object's material",
        h("label", { class: "wide" }, "object ", this.objectSelect),
        this.materialNote,
      ),
      section("light", "Light", h("label", { class: "wide" }, "light ", this.lightSelect)),
    );
    this.form.addEventListener("submit", (e) => e.preventDefault());
  }

  /** A field with its rule from the schema (`object`: the schema of the object holding it), or, without
   * the schema, with the kind its value shows. */
  resolve(spec, object, holder) {
    const r = rule(object, spec.key);
    const current = holder ? holder[spec.key] : undefined;
    const step = r?.integer ? 1 : (spec.step ?? "any");
    return {
      ...spec,
      type: r ? r.kind : kindOfValue(current),
      step,
      ...inputBounds(r, step),
      def: r ? defaultOf(object, spec.key, holder) : undefined,
      options: r?.options ?? (current === undefined ? [] : [current]),
      nullable: !!r?.nullable,
      description: r?.description ?? "",
    };
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
      h(
        "div",
        {
          class: `field${spec.type === "vec3" ? " vec" : ""}${isDefault ? " is-default" : ""}`,
          dataset: { path: path.join(".") },
          title: spec.description || null,
        },
        ...els,
        spec.help ? h("small", { id: `${id}-help` }, spec.help) : null,
      );
    const later = debounce(write, 350);
    if (spec.type === "number") {
      const input = h("input", {
        id,
        type: "number",
        step: spec.step,
        min: spec.min,
        max: spec.max,
        value: value ?? "",
        placeholder: spec.nullable ? "auto" : "",
        "aria-describedby": spec.help ? `${id}-help` : null,
      });
      input.addEventListener("input", () => {
        if (input.value === "" && spec.nullable) return later(null);
        const v = Number(input.value);
        if (input.value !== "" && Number.isFinite(v)) later(v);
      });
      return wrap(h("label", { for: id }, spec.label), input);
    }
    if (spec.type === "vec3") {
      const v = Array.isArray(value) ? value : ["", "", ""];
      const inputs = ["x", "y", "z"].map((axis, i) =>
        h("input", {
          type: "number",
          step: "any",
          min: spec.min,
          max: spec.max,
          value: v[i] ?? "",
          "aria-label": `${spec.label} ${axis}`,
          id: i === 0 ? id : null,
        }),
      );
      for (const input of inputs)
        input.addEventListener("input", () => {
          const xs = inputs.map((x) => Number(x.value));
          if (inputs.every((x) => x.value !== "") && xs.every(Number.isFinite)) later(xs);
        });
      return wrap(h("label", { for: id }, spec.label), h("span", { class: "vec3" }, ...inputs));
    }
    if (spec.type === "rgb") {
      const input = h("input", {
        id,
        type: "text",
        inputmode: "decimal",
        value: showRGB(value, isDefault),
        "aria-describedby": `${id}-help`,
        autocomplete: "off",
        spellcheck: "false",
      });
      input.addEventListener("input", () => {
        const v = parseRGB(input.value);
        input.setAttribute("aria-invalid", v === undefined ? "true" : "false");
        if (v !== undefined) later(v);
      });
      return wrap(h("label", { for: id }, spec.label), input, h("small", { id: `${id}-help` }, "a number, or r, g, b"));
    }
    if (spec.type === "select") {
      const select = h(
        "select",
        { id },
        spec.options.map((o) => h("option", { value: o, selected: o === value }, o)),
      );
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

  /** The controls of one section: `specs` (labels and order), `object` the schema of the object at `base`. */
  fill(section, specs, base, holder, object, filter = () => true) {
    const body = this.sections[section];
    const shown = specs.filter(filter).map((spec) => this.resolve(spec, object, holder));
    const paths = shown.map((spec) => [...base, spec.key].join("."));
    const same =
      paths.join("\n") ===
      $$(".field", body)
        .map((el) => el.dataset.path)
        .join("\n");
    if (same && body.contains(document.activeElement)) {
      // do not rebuild under the student's cursor: update the other controls' values only
      for (const el of $$(".field", body)) {
        const spec = shown[paths.indexOf(el.dataset.path)];
        const given = holder ? holder[spec.key] : undefined;
        const v = given === undefined ? spec.def : given;
        el.classList.toggle("is-default", given === undefined);
        for (const input of $$("input, select", el)) {
          if (input === document.activeElement) continue;
          if (spec.type === "vec3" && Array.isArray(v)) input.value = v[$$("input", el).indexOf(input)];
          else if (spec.type === "rgb" && v !== undefined) input.value = showRGB(v, given === undefined);
          else if (spec.type === "check") input.checked = !!v;
          else if (v !== undefined && v !== null) input.value = v;
        }
      }
      return;
    }
    // rebuild (the fields differ, e.g. another sampler type), keeping the focus on the same field
    const focused = body.contains(document.activeElement)
      ? document.activeElement.closest(".field")?.dataset.path
      : null;
    body.replaceChildren(...shown.map((spec) => this.control(spec, base, holder)));
    if (focused)
      $$(".field", body)
        .find((el) => el.dataset.path === focused)
        ?.querySelector("input, select")
        ?.focus();
  }

  /** Follow the text: `value` is the parsed scene, or null when the JSON does not parse. */
  refresh(value, force = false) {
    const disabled = value === null || typeof value !== "object";
    this.disabledNote.hidden = !disabled;
    this.form.classList.toggle("stale", disabled);
    for (const fs of $$("fieldset", this.form)) fs.disabled = disabled;
    if (disabled) return this.blank();
    if (!force && this.value && JSON.stringify(this.value) === JSON.stringify(value)) return;
    this.value = value;
    const sec = (k) => (value[k] && typeof value[k] === "object" ? value[k] : {});
    this.fill("camera", CAMERA, ["camera"], sec("camera"), part("camera"));
    this.fill("film", FILM, ["film"], sec("film"), part("film"));
    const sampler = sec("sampler");
    const samplerType = withDefaults("sampler", sampler).type;
    this.fill("sampler", SAMPLER, ["sampler"], sampler, part("sampler"), (s) => !s.only || s.only === samplerType);
    this.fill("render", RENDER, ["render"], sec("render"), part("render"));

    const objects = Array.isArray(value.objects) ? value.objects : [];
    this.objectIndex = Math.min(this.objectIndex, Math.max(0, objects.length - 1));
    const objectLabels = objects.map((o, i) => `${i}: ${(o?.name) || (o?.type) || "?"}`);
    if (
      objectLabels.join("\n") !==
      $$("option", this.objectSelect)
        .map((o) => o.textContent)
        .join("\n")
    ) {
      this.objectSelect.replaceChildren(...objectLabels.map((l, i) => h("option", { value: i }, l)));
    }
    this.objectSelect.value = String(this.objectIndex);
    const obj = objects[this.objectIndex];
    if (obj && typeof obj.material === "string") {
      const users = objects.filter((o) => o && o.material === obj.material).length;
      const mats = value.materials && typeof value.materials === "object" ? value.materials : {};
      this.materialNote.textContent = `material "${obj.material}"${users > 1 ? `, shared by ${users} objects` : ""}`;
      this.fill("material", MATERIAL, ["materials", obj.material], mats[obj.material] || {}, part("material"));
    } else if (obj?.material && typeof obj.material === "object") {
      this.materialNote.textContent = "an inline material";
      this.fill("material", MATERIAL, ["objects", this.objectIndex, "material"], obj.material, part("material"));
    } else {
      this.materialNote.textContent = objects.length ? "this object has no material yet" : "no objects";
      this.sections.material.replaceChildren();
    }

    const lights = Array.isArray(value.lights) ? value.lights : [];
    this.lightIndex = Math.min(this.lightIndex, Math.max(0, lights.length - 1));
    const lightLabels = lights.map((l, i) => `${i}: ${l?.type || "?"}`);
    if (
      lightLabels.join("\n") !==
      $$("option", this.lightSelect)
        .map((o) => o.textContent)
        .join("\n")
    ) {
      this.lightSelect.replaceChildren(...lightLabels.map((l, i) => h("option", { value: i }, l)));
    }
    this.lightSelect.value = String(this.lightIndex);
    const light = lights[this.lightIndex];
    this.fill(
      "light",
      (light && LIGHT_FIELDS[light.type]) || [],
      ["lights", this.lightIndex],
      light || {},
      part("light", light?.type),
    );
  }

  /** While the text does not parse: no control shows a value of an older text (they would look current). */
  blank() {
    for (const input of $$("input", this.form)) {
      if (input.type === "checkbox") input.checked = false;
      else input.value = "";
    }
    for (const select of $$("select", this.form)) select.selectedIndex = -1;
    this.materialNote.textContent = "";
    this.value = null; // the next text that parses fills every control again
  }

  /** The schema came (or changed): rebuild every control with its rules. */
  schemaLoaded() {
    for (const body of Object.values(this.sections)) body.replaceChildren();
    if (this.value) this.refresh(this.value, true);
  }

  /** Follow the Build panel's pick: the material of object `index`, or light `index` (no focus taken). */
  show(list, index) {
    if (!this.value) return;
    if (list === "objects") this.objectIndex = index;
    else this.lightIndex = index;
    this.refresh(this.value, true);
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
