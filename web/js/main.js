// The page: four tabs (workspace, lessons, examples, grading) and the wiring between the editor, the form, the
// viewer and the ray tree. Any unexpected error shows a message in the banner, never a blank page.
import { api, useShareToken } from "./api.js";
import { BuildPanel } from "./build.js";
import { SceneEditor } from "./editor.js";
import { SceneFields } from "./fields.js";
import { formatJSON } from "./jsonpos.js";
import { GradingPanel } from "./grading.js";
import { LESSONS, Lessons } from "./lessons.js";
import { decodeScene, encodeScene, MAX_LINK } from "./share.js";
import { RadiosityPanel } from "./radiosity.js";
import { RayTreePanel } from "./raytree.js";
import { loadSchema } from "./schema.js";
import { $, $$, benignError, download, h } from "./util.js";
import { copyText, Viewer } from "./viewer.js";
import { identityJobs, showWorkingOn } from "./course/working.js";

const banner = $("#banner");
function notify(text, kind = "error", action = null) {
  banner.hidden = false;
  banner.dataset.kind = kind;
  const parts = [h("span", {}, text)];
  if (action) parts.push(h("button", { type: "button", onclick: action.run }, action.label));
  parts.push(
    h(
      "button",
      { type: "button", class: "close", "aria-label": "Dismiss", onclick: () => (banner.hidden = true) },
      "×",
    ),
  );
  banner.replaceChildren(...parts);
}
window.addEventListener("error", (e) => benignError(e) || notify(`Something went wrong on this page: ${e.message}`));
window.addEventListener("unhandledrejection", (e) =>
  notify(`Something went wrong on this page: ${e.reason?.message || e.reason}`),
);

// -- tabs, and the address: each tab and lesson has its own (#lessons/bounces), so Back and Forward work -------

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
  if (page === "examples") gallery();
  if (page === "grading") grading.open();
}

/** The address of a tab: the workspace is the page itself, the lessons tab names the lesson shown. */
function tabHash(id) {
  const page = id.replace("tab-", "");
  if (page === "work") return "";
  if (page === "lessons" && lessons?.current) return `#lessons/${lessons.current}`;
  return `#${page}`;
}

/** Go to an address: a new entry in the history (Back comes here again), then the page follows it. */
function go(hash) {
  if (location.hash === hash || (!hash && !location.hash)) return;
  history.pushState(null, "", hash || location.pathname + location.search);
  route();
}

tabs.forEach((t, i) => {
  t.addEventListener("click", () => go(tabHash(t.id)));
  t.addEventListener("keydown", (e) => {
    const k = { ArrowRight: 1, ArrowLeft: -1 }[e.key];
    if (!k) return;
    const next = tabs[(i + k + tabs.length) % tabs.length].id;
    go(tabHash(next));
    selectTab(next, true);
  });
});

/** Show what the address names: #work (or nothing), #lessons, #lessons/<id>, #examples, #grading;
 * #scene/<data> (a scene to open in the editor) and #shared/<job>/<token> (a job to view, read-only). */
async function route() {
  let parts;
  try {
    parts = decodeURIComponent(location.hash.slice(1)).split("/");
  } catch {
    parts = location.hash.slice(1).split("/"); // a broken %-escape: taken as it is
  }
  const [page, ...rest] = parts;
  if (page === "lessons") {
    selectTab("tab-lessons");
    const id = rest[0];
    if (!id) return;
    if (!LESSONS.some((l) => l.id === id)) {
      notify(`There is no lesson '${id}': choose one from the list.`, "warn");
      return;
    }
    if (lessons.current !== id) lessons.run(id); // not awaited: it follows its panels to their end
  } else if (page === "examples" || page === "grading") selectTab(`tab-${page}`);
  else if (page === "scene") {
    history.replaceState(null, "", location.pathname + location.search); // the editor keeps the scene from here
    selectTab("tab-work");
    await openSceneLink(rest.join("/"));
  } else if (page === "shared") {
    selectTab("tab-work");
    await openSharedJob(rest[0], rest[1]);
  } else selectTab("tab-work");
}
window.addEventListener("popstate", () => route());

// -- the workspace --------------------------------------------------------------------------------

const fieldsForm = $("#fields-form");
let fields = null;
let build = null;
const editor = new SceneEditor($("#editor-panel"), {
  onChange: (state) => {
    fields?.refresh(state.value);
    followExample(state.value);
    build?.refresh(state.value);
    if (state.value)
      $("#scene-description").textContent = typeof state.value.description === "string" ? state.value.description : "";
  },
  onRender: () => viewer.submit(),
  onHistory: (canUndo, canRedo) => {
    $("#btn-undo").disabled = !canUndo;
    $("#btn-redo").disabled = !canRedo;
  },
  onTravel: (kind, what) => build?.travelled(kind, what),
});
fields = new SceneFields(fieldsForm, editor);
$("#btn-undo").addEventListener("click", () => editor.undo());
$("#btn-redo").addEventListener("click", () => editor.redo());
// the Build panel's pick shows the same object (its material) or light in the form
build = new BuildPanel($("#build"), editor, {
  onPicked: ([list, i]) => fields.show(list, i),
  onLoad: (text, name) => loadText(text, name, false),
  notify,
});
if (window.matchMedia("(max-width: 820px)").matches) {
  // a phone: the Build panel and the fields fold away, so that the viewer comes sooner under the Render button
  $("details.fields").open = false;
  $("#build-details").open = false;
}

const viewer = new Viewer({
  getScene: () => {
    const st = editor.parseNow();
    if (st.syntax) {
      editor.validate();
      throw new Error(`Fix the JSON syntax error first (line ${st.syntax.line}, column ${st.syntax.col}).`);
    }
    if (st.valid === false && st.errors.length && st.checked === st.text) {
      const n = st.errors.length;
      throw new Error(
        `The scene has ${n} error${n > 1 ? "s" : ""}, marked in the editor: fix ${n > 1 ? "them" : "it"} first.`,
      );
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
  // the picture picks what its pixel shows for the Build panel (the editor's scene, through this picture's film)
  const found = build.pickPixel(x, y, view.width, view.height);
  try {
    await viewer.sceneOf(view);
  } catch (err) {
    raytree.status("error", `Could not load the job's scene: ${err.message}.`);
    return;
  }
  const camera = (s) =>
    JSON.stringify([s?.camera?.lookfrom, s?.camera?.lookat, s?.camera?.vup ?? [0, 1, 0], s?.camera?.vfov]);
  if (view.scene && camera(view.scene) !== camera(editor.parseNow().value)) {
    build.say(
      "This picture was rendered with another camera than the editor's: the pick follows the editor's camera, so it may not be what the picture shows there. Render again to pick in the picture.",
      true,
    );
  }
  const first = $("#raytree").hidden;
  const shown = raytree.show(view, viewer.image(), x, y);
  viewer.layout(); // a smaller picture where the tree shares its column (app.css)
  const box = $("#raytree").getBoundingClientRect();
  if (first || box.top > window.innerHeight - 160) {
    // the tree under the picture (a wide window): the picture at the top, the tree below it; else the tree itself
    const beside = Math.abs(box.left - $("#stage").getBoundingClientRect().left) < 40;
    (beside ? $("#stage") : $("#raytree")).scrollIntoView({ behavior: "smooth", block: "start" });
  }
  const tree = await shown;
  // a mesh file's triangles are the server's alone: its ray tree says what the pixel shows (the editor's scene)
  if (tree && JSON.stringify(view.scene) === JSON.stringify(editor.parseNow().value)) build.pickFromTree(tree, found);
}

let previousText = null;
let exampleName = null; // the example the editor's text came from (loaded, or restored from the last visit)
/** The Example menu names the example the editor holds (loaded, or restored from the last visit), else none. */
function showExample(name) {
  exampleName = name;
  followExample(editor.parseNow().value);
}

/** The menu follows the text: it names the example while the text is that scene (as loaded, or edited and still
 * called by the example's name); other text, typed or pasted (or text that does not parse), resets it. */
function followExample(value) {
  const example = examples.find((s) => s.name === exampleName);
  exampleSelect.value = example && value && value.name === example.title ? example.name : "";
}

function loadText(text, name, show = true) {
  previousText = editor.text;
  editor.setText(text, name);
  showExample(name);
  if (show) {
    go("");
    selectTab("tab-work");
  }
  editor.setStatus("ok", `Loaded ${name}.`);
  const undo = h("button", { type: "button", class: "small" }, "Undo");
  undo.addEventListener("click", () => {
    if (previousText !== null) editor.setText(previousText);
    previousText = null;
    undo.remove();
  });
  $("#load-note").replaceChildren(h("span", {}, `Loaded ${name}. `), undo);
}

let exampleAsked = 0;

async function loadExample(name, show = true) {
  // two examples chosen in a row may answer out of order: the editor gets the one chosen last (the menu names it)
  const asked = ++exampleAsked;
  try {
    const text = formatJSON(await api.scene(name));
    if (asked === exampleAsked) loadText(text, name, show);
  } catch (err) {
    if (asked === exampleAsked) notify(`Could not load the example ${name}: ${err.message}.`);
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
// -- links: a scene to open in the editor, a job to view read-only ----------------------------------

$("#btn-share-scene").addEventListener("click", async () => {
  const note = $("#load-note");
  const st = editor.parseNow();
  if (st.syntax) {
    note.replaceChildren(
      h(
        "span",
        {},
        `Fix the JSON syntax error first (line ${st.syntax.line}, column ${st.syntax.col}): a link carries a scene that parses.`,
      ),
    );
    return;
  }
  const data = await encodeScene(JSON.stringify(st.value));
  const url = `${location.origin}${location.pathname}#scene/${data}`;
  if (url.length > MAX_LINK) {
    note.replaceChildren(
      h(
        "span",
        { class: "bad" },
        `This scene is too large for a link (${Math.ceil(url.length / 1000)} KB compressed; a link holds at most ${MAX_LINK / 1000} KB). Use "Save file" and send the file instead.`,
      ),
    );
    return;
  }
  const field = h("input", {
    type: "text",
    readonly: true,
    value: url,
    class: "share-link",
    "aria-label": "link that opens this scene in the editor",
  });
  const copy = h("button", { type: "button", class: "small" }, "Copy");
  copy.addEventListener("click", () => copyText(field, copy));
  note.replaceChildren(
    h("span", {}, "Link to this scene (it opens in the editor of whoever follows it): "),
    field,
    copy,
  );
  field.select();
});

async function openSceneLink(data) {
  let text;
  try {
    text = await decodeScene(data);
    JSON.parse(text);
  } catch (err) {
    notify(
      `This link does not hold a scene the editor can open (${err.message}). Ask for the link again, or for the scene as a file.`,
    );
    return;
  }
  loadText(formatJSON(JSON.parse(text)), "the scene of a link");
}

async function openSharedJob(id, token) {
  if (!id || !token) {
    notify("This link to a shared job is cut short: it needs the job's id and its share token (#shared/<id>/<token>).");
    return;
  }
  useShareToken(id, token);
  let job;
  try {
    job = await api.job(id);
  } catch (err) {
    const why =
      err.status === 404
        ? "there is no such job, or the link's token is not its share token (or the job was removed)"
        : err.message;
    viewer.message("error", `Could not open the shared job: ${why}.`);
    $("#viewer-panel").dataset.shared = "missing";
    return;
  }
  await viewer.show(job, null, null, { shared: true });
}

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
const cards = new Map(); // example name -> {root, img, state}
let polling = null;

/** The gallery: each example's preview once a render worker has made it, and meanwhile its state. */
function gallery() {
  if (!examples.length) return;
  if (!galleryBuilt) {
    galleryBuilt = true;
    $("#gallery").replaceChildren(
      ...examples.map((s) => {
        const img = h("img", { alt: `render of ${s.name}`, width: 256, height: 192, hidden: true });
        const state = h("p", { class: "preview-state", role: "status" });
        const root = h(
          "article",
          { class: "card", dataset: { name: s.name } },
          h("h2", {}, s.title),
          h("div", { class: "card-image" }, img, state),
          h("p", {}, s.description),
          h(
            "div",
            { class: "card-actions" },
            h("button", { type: "button", onclick: () => loadExample(s.name) }, "Open in the editor"),
            h("a", { href: `/api/scenes/${encodeURIComponent(s.name)}` }, `scenes/${s.name}.json`),
          ),
        );
        cards.set(s.name, { root, img, state, asked: false });
        return root;
      }),
    );
  }
  paintCards();
}

function paintCards() {
  let waiting = false;
  for (const s of examples) {
    const card = cards.get(s.name);
    const p = s.preview || { state: "none" };
    card.root.dataset.preview = p.state;
    if (p.state === "ready") {
      if (!card.img.getAttribute("src")) card.img.src = api.previewUrl(s.name);
      card.img.hidden = false;
      card.state.hidden = true;
      continue;
    }
    card.state.hidden = false;
    card.state.textContent =
      p.state === "failed"
        ? `Could not render the preview: ${p.error}`
        : p.state === "rendering"
          ? `Rendering the preview… ${Math.round(100 * (p.fraction || 0))}%`
          : p.state === "queued"
            ? "The preview waits for a render worker…"
            : "Asking for the preview…";
    if (p.state === "failed") continue;
    waiting = true;
    if (p.state === "none" && !card.asked) {
      card.asked = true; // the server then queues it (a server that does not render the previews ahead)
      api.askPreview(s.name).catch(() => {});
    }
  }
  clearTimeout(polling);
  if (waiting) polling = setTimeout(refreshPreviews, 1000);
}

let previewsAsked = 0;

async function refreshPreviews() {
  if ($("#page-examples").hidden) return; // looked at again when the tab is shown
  // a look asked before the tab was shown again may answer after the one asked then: only the latest is painted
  // (an older answer would put a ready card back to "rendering" with its picture still shown)
  const asked = ++previewsAsked;
  try {
    const answer = await api.scenes();
    if (asked !== previewsAsked) return;
    examples = answer;
  } catch {
    // the next look tries again
  }
  paintCards();
}

let lessons = null;

async function start() {
  showWorkingOn($("#working-on")); // opened from an assignment's "Start": the way back to it
  lessons = new Lessons($("#page-lessons"), {
    // a lesson chosen (the list, the menu above a lesson, Next) gets its own address, so Back returns to the one before
    onChoose: (id) => location.hash !== `#lessons/${id}` && history.pushState(null, "", `#lessons/${id}`),
    openInWorkspace: async (scene, job, label, marks = []) => {
      loadText(formatJSON(scene), label);
      viewer.remember(job);
      await viewer.show(job, scene, JSON.stringify(scene));
      const [mark] = marks; // the pixel the lesson asks about, marked on the picture here as on the lesson's
      if (mark) {
        viewer.markPixel(mark.x, mark.y, `The lesson's pixel (${mark.x}, ${mark.y}) is marked`);
        $("#stage").scrollIntoView({ block: "nearest" });
      }
    },
  });
  // the form's rules (kinds, bounds, defaults) are the server's; without them it still shows the text's values
  const schema = loadSchema().then(
    () => fields.schemaLoaded(),
    () => {},
  );
  try {
    examples = await api.scenes();
    exampleSelect.replaceChildren(
      h("option", { value: "" }, "Open an example…"),
      ...examples.map((s) => h("option", { value: s.name }, s.title)),
    );
  } catch (err) {
    notify(`Could not reach the server: ${err.message}. The editor still works; rendering needs the server.`, "error", {
      label: "Reload",
      run: () => location.reload(),
    });
  }
  if (!editor.restore()) {
    if (examples.some((s) => s.name === "whitted")) await loadExample("whitted", false);
    else editor.setText('{\n  "version": 1\n}\n');
    $("#load-note").replaceChildren();
  } else showExample(editor.name);
  await schema;
  selectTab("tab-work");
  viewer.renderList();
  const shared = location.hash.startsWith("#shared/");
  if (!shared) await viewer.restore().catch((err) => notify(`Could not load your jobs: ${err.message}.`));
  await route();
  if (shared) await viewer.restore({ show: false }).catch((err) => notify(`Could not load your jobs: ${err.message}.`));
  // an assignment's link made this browser a student's: their jobs from another browser join "my jobs"
  for (const job of (await identityJobs().catch(() => [])).reverse())
    if (!viewer.jobs.has(job.id)) viewer.remember(job);
  document.body.dataset.ready = "true";
}

start();
