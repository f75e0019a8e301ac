// The page: four tabs (workspace, lessons, examples, grading) and the wiring between the editor, the form, the
// viewer and the ray tree. Any unexpected error shows a message in the banner, never a blank page.
import { api } from "./api.js";
import { SceneEditor } from "./editor.js";
import { SceneFields } from "./fields.js";
import { formatJSON } from "./jsonpos.js";
import { GradingPanel } from "./grading.js";
import { Lessons } from "./lessons.js";
import { RadiosityPanel } from "./radiosity.js";
import { RayTreePanel } from "./raytree.js";
import { loadSchema } from "./schema.js";
import { $, $$, download, h } from "./util.js";
import { Viewer } from "./viewer.js";

const banner = $("#banner");
function notify(text, kind = "error", action = null) {
  banner.hidden = false;
  banner.dataset.kind = kind;
  const parts = [h("span", {}, text)];
  if (action) parts.push(h("button", { type: "button", onclick: action.run }, action.label));
  parts.push(h("button", { type: "button", class: "close", "aria-label": "Dismiss", onclick: () => (banner.hidden = true) }, "×"));
  banner.replaceChildren(...parts);
}
window.addEventListener("error", (e) => notify(`Something went wrong on this page: ${e.message}`));
window.addEventListener("unhandledrejection", (e) => notify(`Something went wrong on this page: ${e.reason?.message || e.reason}`));

// -- tabs -----------------------------------------------------------------------------------------

const tabs = $$("[role=tab]");
function selectTab(id, focus = false) {
  for (const t of tabs) {
    const on = t.id === id;
    t.setAttribute("aria-selected", String(on));
    t.tabIndex = on ? 0 : -1;
    $(`#${t.getAttribute("aria-controls")}`).hidden = !on;
    if (on && focus) t.focus();
  }
  const page = id.replace("tab-", "");
  if (location.hash !== `#${page}`) history.replaceState(null, "", page === "work" ? location.pathname : `#${page}`);
  if (page === "examples") gallery();
  if (page === "grading") grading.open();
}
tabs.forEach((t, i) => {
  t.addEventListener("click", () => selectTab(t.id));
  t.addEventListener("keydown", (e) => {
    const k = { ArrowRight: 1, ArrowLeft: -1 }[e.key];
    if (k) selectTab(tabs[(i + k + tabs.length) % tabs.length].id, true);
  });
});

// -- the workspace --------------------------------------------------------------------------------

const fieldsForm = $("#fields-form");
let fields = null;
const editor = new SceneEditor($("#editor-panel"), {
  onChange: (state) => {
    fields?.refresh(state.value);
    if (state.value) $("#scene-description").textContent = typeof state.value.description === "string" ? state.value.description : "";
  },
  onRender: () => viewer.submit(),
});
fields = new SceneFields(fieldsForm, editor);
if (window.matchMedia("(max-width: 820px)").matches) $("details.fields").open = false; // a phone: the viewer comes sooner

const viewer = new Viewer({
  getScene: () => {
    const st = editor.parseNow();
    if (st.syntax) {
      editor.validate();
      throw new Error(`Fix the JSON syntax error first (line ${st.syntax.line}, column ${st.syntax.col}).`);
    }
    if (st.valid === false && st.errors.length && st.checked === st.text) {
      const n = st.errors.length;
      throw new Error(`The scene has ${n} error${n > 1 ? "s" : ""}, marked in the editor: fix ${n > 1 ? "them" : "it"} first.`);
    }
    return { text: st.text, value: st.value };
  },
  onPick: (view, x, y) => pickPixel(view, x, y),
  onLoadScene: (scene, name) => loadText(formatJSON(scene), name),
  notify,
});
viewer.onRefused = (errors) => editor.showProblems(errors);
const radiosity = new RadiosityPanel({ sceneOf: (view) => viewer.sceneOf(view) });
viewer.onJob = (view) => radiosity.update(view);

const raytree = new RayTreePanel({
  onPick: (x, y) => viewer.view && viewer.pick(x, y),
  onEditObject: (index) => {
    const scene = viewer.view?.scene;
    if (scene && JSON.stringify(scene) !== JSON.stringify(editor.parseNow().value)) {
      notify("The editor holds another scene than the one rendered: its objects may differ.", "warn");
    }
    fields.selectObject(index);
  },
});

async function pickPixel(view, x, y) {
  try {
    await viewer.sceneOf(view);
  } catch (err) {
    raytree.status("error", `Could not load the job's scene: ${err.message}.`);
    return;
  }
  const first = $("#raytree").hidden;
  const shown = raytree.show(view, viewer.image(), x, y);
  if (first || $("#raytree").getBoundingClientRect().top > window.innerHeight) $("#raytree").scrollIntoView({ behavior: "smooth", block: "start" });
  await shown;
}

let previousText = null;
function loadText(text, name, show = true) {
  previousText = editor.text;
  editor.setText(text, name);
  if (show) selectTab("tab-work");
  editor.setStatus("ok", `Loaded ${name}.`);
  const undo = h("button", { type: "button", class: "small" }, "Undo");
  undo.addEventListener("click", () => {
    if (previousText !== null) editor.setText(previousText);
    previousText = null;
    undo.remove();
  });
  $("#load-note").replaceChildren(h("span", {}, `Loaded ${name}. `), undo);
}

async function loadExample(name, show = true) {
  try {
    loadText(formatJSON(await api.scene(name)), name, show);
  } catch (err) {
    notify(`Could not load the example ${name}: ${err.message}.`);
  }
}

const exampleSelect = $("#example-select");
exampleSelect.addEventListener("change", () => {
  if (exampleSelect.value) loadExample(exampleSelect.value);
});

$("#btn-open-file").addEventListener("click", () => $("#file-input").click());
$("#file-input").addEventListener("change", async (e) => {
  const file = e.target.files[0];
  if (!file) return;
  loadText(await file.text(), file.name.replace(/\.json$/i, ""));
  e.target.value = "";
});
$("#btn-save-file").addEventListener("click", () => {
  const name = (editor.parseNow().value?.name || editor.name || "scene").replace(/[^A-Za-z0-9_-]+/g, "_").slice(0, 60);
  download(`${name}.json`, new Blob([editor.text], { type: "application/json" }));
});
$("#btn-format").addEventListener("click", () => {
  const st = editor.parseNow();
  if (st.syntax) return editor.validate();
  editor.setText(formatJSON(st.value));
});

// -- grading (the instructor's view: web/js/grading.js) --------------------------------------------

const grading = new GradingPanel($("#page-grading"));

// -- examples (the scene picker and the gallery) --------------------------------------------------

let examples = [];
let galleryBuilt = false;
function gallery() {
  if (galleryBuilt || !examples.length) return;
  galleryBuilt = true;
  $("#gallery").replaceChildren(
    ...examples.map((s) =>
      h(
        "article",
        { class: "card" },
        h("h2", {}, s.title),
        h("img", { src: api.previewUrl(s.name), alt: `render of ${s.name}`, loading: "lazy", width: 256, height: 192, onerror: (e) => (e.target.alt = `could not render ${s.name}`) }),
        h("p", {}, s.description),
        h("div", { class: "card-actions" }, h("button", { type: "button", onclick: () => loadExample(s.name) }, "Open in the editor"), h("a", { href: `/api/scenes/${encodeURIComponent(s.name)}` }, `scenes/${s.name}.json`)),
      ),
    ),
  );
}

async function start() {
  const page = location.hash.slice(1);
  const lessons = new Lessons($("#page-lessons"), {
    openInWorkspace: async (scene, job, label) => {
      loadText(formatJSON(scene), label);
      viewer.remember(job);
      await viewer.show(job, scene, JSON.stringify(scene));
    },
  });
  void lessons;
  // the form's rules (kinds, bounds, defaults) are the server's; without them it still shows the text's values
  const schema = loadSchema().then(
    () => fields.schemaLoaded(),
    () => {},
  );
  try {
    examples = await api.scenes();
    exampleSelect.replaceChildren(h("option", { value: "" }, "Open an example…"), ...examples.map((s) => h("option", { value: s.name }, s.title)));
  } catch (err) {
    notify(`Could not reach the server: ${err.message}. The editor still works; rendering needs the server.`, "error", { label: "Reload", run: () => location.reload() });
  }
  if (!editor.restore()) {
    if (examples.some((s) => s.name === "whitted")) await loadExample("whitted", false);
    else editor.setText('{\n  "version": 1\n}\n');
    $("#load-note").replaceChildren();
  }
  await schema;
  selectTab(["lessons", "examples", "grading"].includes(page) ? `tab-${page}` : "tab-work");
  viewer.renderList();
  await viewer.restore().catch((err) => notify(`Could not load your jobs: ${err.message}.`));
  document.body.dataset.ready = "true";
}

start();
