// The instructor's grading view (the "Grading" tab): an assignment (JSON) and the class's submissions
// (scenes, images or one zip) are uploaded as multipart/form-data to POST /api/grade/upload (the browser
// streams the files from disk: a class of any size within the server's caps); the run is followed with
// GET /api/grade/{id} until
// it is done, then the class is shown as a table (a column per test) and each student's detail as
// their picture, the reference, the FLIP error map and the rejected pixels, with every test's output.
// Every request carries the instructor's token (a field of the tab, kept in localStorage): a server with
// TRACER_INSTRUCTOR_TOKEN answers grading to it alone; pictures and files come as blob: URLs.
import { ApiError, downloadFile, openFile, request, showImage, tokens } from "./api.js";
import { locate, nodeLine, lineIndex, parse } from "./jsonpos.js";
import { TableSort } from "./sorttable.js";
import { $, h, num, store } from "./util.js";

const POLL_MS = 500;
const KINDS = { json: "scene", png: "png", exr: "exr", zip: "zip" };
const KIND_TEXT = { scene: "scene (JSON)", png: "image (PNG)", exr: "image (EXR)", zip: "class (zip)" };
const TEST_ORDER = { validity: 0, requirement: 1, image: 2 }; // the table's test columns, by kind
const PICTURES = [
  ["render", "their render"],
  ["reference", "the reference"],
  ["error_map", "FLIP error map"],
  ["rejected", "rejected pixels"],
];
const METRICS = [
  // key, header, formatting, which way is better (for the sort's first click)
  ["flip", "FLIP", (x) => fixed(x, 3), 1],
  ["ssim", "SSIM", (x) => fixed(x, 3), -1],
  ["psnr", "PSNR (dB)", (x) => fixed(x, 1), -1],
  ["rejected", "rejected", (x) => (x === null || x === undefined ? "–" : `${fixed(100 * x, 2)} %`), 1],
];

const AS = { as: "instructor" }; // the token grading's requests carry
const grade = {
  example: () => request("GET", "/api/grade/example", undefined, AS),
  // file names -> the student ids the grader will use: the server's rule (tracer.grading.student_for_file), not a copy
  students: (files) => request("POST", "/api/grade/students", { files }, AS),
  start: (form) => request("POST", "/api/grade/upload", form, AS), // FormData: assignment, then class or files
  state: (id) => request("GET", `/api/grade/${encodeURIComponent(id)}`, undefined, AS),
  summaryUrl: (id, fmt) => `/api/grade/${encodeURIComponent(id)}/summary.${fmt}`,
  fileUrl: (id, student, file) =>
    `/api/grade/${encodeURIComponent(id)}/students/${encodeURIComponent(student)}/${file}`,
};

function fixed(x, digits) {
  return typeof x === "number" && Number.isFinite(x) ? x.toFixed(digits) : "–";
}

/** A score without trailing zeros: 13, 6.5. */
function pts(x) {
  return typeof x === "number" ? num(Math.round(x * 1000) / 1000, 4) : "–";
}

/** A percentage to one decimal without a trailing zero: 46.2 %, 100 %. */
function percentText(x) {
  return typeof x === "number" && Number.isFinite(x) ? `${num(Math.round(x * 10) / 10, 4)} %` : "–";
}

/** A report's score as a percentage of its maximum (scenes and images are out of different totals). */
function share(r) {
  return r.max_score > 0 ? (100 * r.score) / r.max_score : null;
}

function sizeText(bytes) {
  if (bytes < 1024) return `${bytes} B`;
  if (bytes < 1024 * 1024) return `${(bytes / 1024).toFixed(1)} KB`;
  return `${(bytes / 1024 / 1024).toFixed(1)} MB`;
}

/** Why the server refused a grading request for want of the instructor's token (401, 403), or null. */
function tokenProblem(err) {
  if (!(err instanceof ApiError)) return null;
  if (err.status === 403) return `The server has no instructor: ${err.message}`;
  if (err.status === 401)
    return tokens.instructor()
      ? "The server refused the instructor token: check it above."
      : "The server needs the instructor's token: enter it above.";
  return null;
}

/** A picture of a run (it needs the instructor's token): an <img> that shows it once fetched. */
function picture(url, alt) {
  const img = h("img", { alt });
  showImage(img, url, AS);
  return img;
}

/** The bytes of base64 text (the example's images) as a Blob, to upload like a picked file. */
function blobOf(text, type) {
  const raw = atob(text);
  const bytes = new Uint8Array(raw.length);
  for (let i = 0; i < raw.length; i++) bytes[i] = raw.charCodeAt(i);
  return new Blob([bytes], { type });
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

export class GradingPanel {
  constructor(root) {
    this.root = root;
    this.subs = []; // [{student, kind: scene|png|exr|zip, file (a File or Blob), name (the file's name), bytes, from}]
    this.run = null; // the last state of the run shown
    this.token = 0; // bumps when a new run starts: an older poll stops
    this.sort = new TableSort("student");
    this.built = false;
  }

  /** Called when the tab is shown: the view is built the first time, and the last run comes back. */
  open() {
    if (this.built) return;
    this.built = true;
    this.build();
    const last = store.get("grading.run");
    if (typeof last === "string" && /^[0-9a-f]{32}$/.test(last)) this.follow(last, { quiet: true });
  }

  build() {
    this.text = h("textarea", {
      id: "grade-assignment",
      class: "grade-json",
      wrap: "off",
      spellcheck: "false",
      autocomplete: "off",
      autocapitalize: "off",
      "aria-describedby": "grade-assignment-help grade-errors",
      placeholder: '{"version": 1, "name": "HW 4", "requirements": [...], "reference": {"scene": {...}}}',
    });
    this.errors = h("ul", {
      id: "grade-errors",
      class: "grade-errors",
      "aria-label": "Problems in the request",
      "aria-live": "polite",
    });
    this.note = h("p", { id: "grade-load-note", class: "note", "aria-live": "polite" });
    const editor = h(
      "section",
      { class: "panel grade-editor", "aria-labelledby": "h-grade-assignment" },
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-grade-assignment" }, "Assignment"),
        h(
          "span",
          { class: "toolbar" },
          h(
            "button",
            { type: "button", id: "grade-load-example", onclick: () => this.loadExample() },
            "Load the example",
          ),
        ),
      ),
      this.note,
      h(
        "label",
        { for: "grade-assignment", class: "grade-label" },
        "The assignment as JSON (its reference scene inline)",
      ),
      this.text,
      h(
        "p",
        { id: "grade-assignment-help", class: "hint" },
        "The format: docs/grading.md (",
        h("code", {}, "render"),
        ", ",
        h("code", {}, "limits"),
        ", ",
        h("code", {}, "validity"),
        ", ",
        h("code", {}, "requirements"),
        ", ",
        h("code", {}, "reference"),
        "). Problems the server finds are listed here with their place in the text.",
      ),
      this.errors,
    );

    this.fileInput = h("input", {
      type: "file",
      id: "grade-files",
      multiple: true,
      accept: ".json,.png,.exr,.zip,application/json,image/png,application/zip",
      hidden: true,
    });
    this.fileInput.addEventListener("change", () =>
      this.addFiles([...this.fileInput.files]).finally(() => (this.fileInput.value = "")),
    );
    this.subList = h("tbody", { id: "grade-sub-rows" });
    this.subCount = h("span", { class: "muted", id: "grade-sub-count" });
    this.subErrors = h("ul", {
      id: "grade-sub-errors",
      class: "grade-errors",
      "aria-label": "Problems with the submissions",
      "aria-live": "polite",
    });
    this.gradeButton = h(
      "button",
      { type: "button", id: "grade-start", class: "primary", onclick: () => this.start() },
      "Grade",
    );
    this.progress = h("progress", {
      id: "grade-progress",
      max: 1,
      value: 0,
      "aria-label": "renders done",
      hidden: true,
    });
    this.status = h("p", { id: "grade-status", role: "status", "aria-live": "polite" });
    const submissions = h(
      "section",
      { class: "panel grade-subs", "aria-labelledby": "h-grade-subs" },
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-grade-subs" }, "Submissions"),
        this.subCount,
        h(
          "span",
          { class: "toolbar" },
          h(
            "button",
            {
              type: "button",
              id: "grade-pick",
              "aria-describedby": "grade-files-help",
              onclick: () => this.fileInput.click(),
            },
            "Add files…",
          ),
          h("button", { type: "button", id: "grade-clear", onclick: () => this.setSubs([]) }, "Clear"),
        ),
      ),
      this.fileInput,
      h(
        "p",
        { id: "grade-files-help", class: "hint" },
        "Scenes (.json) and images of the reference scene from the students' own ray tracers (.png, .exr), one file per student named after them; or the whole class as one .zip (a file or a folder per student).",
      ),
      h(
        "div",
        { class: "grade-sub-box" },
        h(
          "table",
          { class: "grade-sub-table" },
          h("caption", { class: "sr-only" }, "Submissions to grade"),
          h(
            "thead",
            {},
            h(
              "tr",
              {},
              h("th", { scope: "col" }, "Student"),
              h("th", { scope: "col" }, "Kind"),
              h("th", { scope: "col" }, "Size"),
              h("th", { scope: "col" }, h("span", { class: "sr-only" }, "Remove")),
            ),
          ),
          this.subList,
        ),
      ),
      this.subErrors,
      h("div", { class: "grade-go" }, this.gradeButton, this.progress),
      this.status,
    );

    this.results = h("section", {
      class: "panel grade-results",
      id: "grade-results",
      "aria-labelledby": "h-grade-results",
      hidden: true,
    });
    this.detail = h("section", {
      class: "panel grade-detail",
      id: "grade-detail",
      "aria-labelledby": "h-grade-detail",
      hidden: true,
    });
    this.tokenInput = h("input", {
      type: "password",
      id: "grade-token",
      autocomplete: "off",
      spellcheck: "false",
      "aria-describedby": "grade-token-help",
      value: tokens.instructor() || "",
      placeholder: "the server's TRACER_INSTRUCTOR_TOKEN",
    });
    this.tokenInput.addEventListener("change", () => {
      tokens.setInstructor(this.tokenInput.value.trim());
      this.tokenInput.removeAttribute("aria-invalid");
      const last = store.get("grading.run");
      if (typeof last === "string" && !this.run) this.follow(last, { quiet: true });
    });
    const access = h(
      "div",
      { class: "panel grade-access" },
      h("label", { for: "grade-token" }, "Instructor token"),
      this.tokenInput,
      h(
        "p",
        { id: "grade-token-help", class: "hint" },
        "Grading is the instructor's: a server started with TRACER_INSTRUCTOR_TOKEN needs it here (kept in this browser). On your own machine without one, leave it empty.",
      ),
    );
    this.root.replaceChildren(access, h("div", { class: "grading" }, editor, submissions), this.results, this.detail);
    this.renderSubs();
  }

  // -- the assignment and the submissions ---------------------------------------------------------

  async loadExample() {
    const button = $("#grade-load-example", this.root);
    button.disabled = true;
    try {
      const ex = await grade.example();
      this.text.value = `${JSON.stringify(ex.assignment, null, 2)}\n`;
      this.setSubs(
        ex.submissions.map((s) =>
          s.image !== undefined
            ? {
                student: s.student,
                kind: s.format || "png",
                file: blobOf(s.image, `image/${s.format || "png"}`),
                name: `${s.student}.${s.format || "png"}`,
                bytes: Math.floor((s.image.length * 3) / 4),
                from: "example",
              }
            : {
                student: s.student,
                kind: "scene",
                file: new Blob([s.scene], { type: "application/json" }),
                name: `${s.student}.json`,
                bytes: new Blob([s.scene]).size,
                from: "example",
              },
        ),
      );
      this.showErrors([]);
      this.note.textContent = `Loaded the example: “${ex.assignment.name}” and a class of ${ex.submissions.length} students.`;
    } catch (err) {
      this.note.textContent = "";
      if (tokenProblem(err)) this.needToken(err);
      this.showErrors(
        err instanceof ApiError ? err.errors : [{ path: "", message: String(err.message || err) }],
        "Could not load the example:",
      );
    } finally {
      button.disabled = false;
    }
  }

  /** Files picked: a .zip is the whole class (it replaces the list); other files add or replace students. */
  async addFiles(files) {
    const problems = [];
    let subs;
    const zips = files.filter((f) => /\.zip$/i.test(f.name));
    if (zips.length) {
      if (zips.length > 1 || files.length > 1)
        problems.push({ path: zips[0].name, message: "a zip is the whole class: choose it alone" });
      else
        subs = [
          { student: zips[0].name, kind: "zip", file: zips[0], name: zips[0].name, bytes: zips[0].size, from: "file" },
        ];
      subs ??= this.subs.filter((s) => s.kind !== "zip");
    }
    if (!zips.length) {
      let picked = [];
      for (const f of files) {
        const ext = (/\.([^.]+)$/.exec(f.name)?.[1] || "").toLowerCase();
        const kind = KINDS[ext];
        if (!kind || kind === "zip") {
          problems.push({
            path: f.name,
            message: "not a submission: choose .json scenes, .png or .exr images, or one .zip",
          });
          continue;
        }
        picked.push({ f, kind });
      }
      let ids = [];
      if (picked.length) {
        try {
          ids = (await grade.students(picked.map((p) => p.f.name))).students;
        } catch (err) {
          if (tokenProblem(err)) this.needToken(err);
          problems.push({
            path: "",
            message: `Could not add the files: the server did not name their students (${err.message}).`,
          });
          picked = [];
        }
      }
      // the list as it is now, after the server named the students: files added meanwhile (a drop, then a pick
      // before the first answered) or the example loaded stay; taken before the await, they were lost
      subs = this.subs.filter((s) => s.kind !== "zip");
      for (const [i, { f, kind }] of picked.entries()) {
        const student = ids[i];
        subs = subs.filter((s) => s.student !== student);
        subs.push({ student, kind, file: f, name: f.name, bytes: f.size, from: "file" });
      }
      subs.sort((a, b) => a.student.localeCompare(b.student));
    }
    this.setSubs(subs);
    this.showSubErrors(problems);
  }

  setSubs(subs) {
    this.subs = subs;
    this.showSubErrors([]);
    this.renderSubs();
  }

  renderSubs() {
    const n = this.subs.length;
    const zip = this.subs[0]?.kind === "zip";
    this.subCount.textContent = zip ? "a class in a zip" : n ? `${n} student${n > 1 ? "s" : ""}` : "";
    if (!n) {
      this.subList.replaceChildren(
        h("tr", { class: "empty" }, h("td", { colspan: 4 }, "None yet: add files, or load the example.")),
      );
      return;
    }
    this.subList.replaceChildren(
      ...this.subs.map((s, i) =>
        h(
          "tr",
          { dataset: { student: s.student, kind: s.kind } },
          h("th", { scope: "row" }, s.student),
          h("td", {}, KIND_TEXT[s.kind] || s.kind),
          h("td", { class: "num" }, sizeText(s.bytes)),
          h(
            "td",
            {},
            h(
              "button",
              {
                type: "button",
                class: "small",
                "aria-label": `Remove ${s.student}`,
                onclick: () => this.setSubs(this.subs.filter((_, j) => j !== i)),
              },
              "×",
            ),
          ),
        ),
      ),
    );
  }

  /** The request body, or null after showing why there is none. */
  body() {
    const text = this.text.value;
    let assignment;
    try {
      assignment = parse(text).value;
    } catch (err) {
      const where = err.line ? `line ${err.line}, column ${err.col}` : "";
      this.showErrors(
        [{ path: where, message: err.message.replace("the scene's JSON object", "the JSON object") }],
        "The assignment is not valid JSON:",
      );
      this.text.focus();
      if (err.offset !== undefined) this.text.setSelectionRange(err.offset, err.offset + 1);
      return null;
    }
    if (!assignment || typeof assignment !== "object" || Array.isArray(assignment)) {
      this.showErrors([{ path: "assignment", message: "expected a JSON object" }]);
      return null;
    }
    this.showErrors([]);
    if (!this.subs.length) {
      this.showSubErrors([{ path: "", message: "add the submissions first (files, or load the example)" }]);
      return null;
    }
    // the files themselves, never read here: the browser streams them (the server names students by file name)
    const form = new FormData();
    form.append("assignment", JSON.stringify(assignment));
    if (this.subs[0].kind === "zip") form.append("class", this.subs[0].file, this.subs[0].name);
    else for (const s of this.subs) form.append("files", s.file, s.name);
    return form;
  }

  /** A 422's items: those about the assignment next to the editor (with their line), the rest by the submissions. */
  showErrors(errors, title = null) {
    const list = this.errors;
    list.replaceChildren();
    list.dataset.count = String(errors.length);
    if (!errors.length) return;
    let nodes = null;
    let where = null;
    try {
      nodes = parse(this.text.value).nodes;
      where = lineIndex(this.text.value);
    } catch {
      nodes = null;
    }
    if (title) list.append(h("li", { class: "title" }, title));
    for (const e of errors) {
      const inner = e.path === "assignment" ? "" : e.path.replace(/^assignment\./, "");
      const found = nodes && e.path.startsWith("assignment") ? locate(nodes, inner) : null;
      const line = found ? nodeLine(where, found.node) : null;
      const item = h(
        "li",
        { class: "problem-item" },
        e.path ? h("code", { class: "where" }, e.path) : null,
        h("span", { class: "msg" }, e.message),
        line
          ? h(
              "button",
              {
                type: "button",
                class: "small",
                onclick: () => this.select(found.node),
                "aria-label": `Show line ${line} of the assignment`,
              },
              `line ${line}`,
            )
          : null,
      );
      list.append(item);
    }
  }

  select(node) {
    this.text.focus();
    this.text.setSelectionRange(node.keyStart >= 0 ? node.keyStart : node.start, node.end);
    const line = lineIndex(this.text.value)(node.start).line;
    const lh = parseFloat(getComputedStyle(this.text).lineHeight) || 18;
    this.text.scrollTop = Math.max(0, (line - 3) * lh);
  }

  showSubErrors(errors) {
    this.subErrors.replaceChildren(
      ...errors.map((e) =>
        h(
          "li",
          { class: "problem-item" },
          e.path ? h("code", { class: "where" }, e.path) : null,
          h("span", { class: "msg" }, e.message),
        ),
      ),
    );
  }

  // -- a run --------------------------------------------------------------------------------------

  async start() {
    const body = this.body();
    if (!body) return;
    this.gradeButton.disabled = true;
    this.setStatus("busy", "Sending the assignment and the submissions…");
    let state;
    try {
      state = await grade.start(body);
    } catch (err) {
      this.gradeButton.disabled = false;
      if (err instanceof ApiError && err.status === 422) {
        const mine = err.errors.filter((e) => e.path === "assignment" || e.path.startsWith("assignment."));
        const others = err.errors.filter((e) => !mine.includes(e));
        this.showErrors(mine, mine.length ? "The server refused the assignment:" : null);
        this.showSubErrors(others);
        this.setStatus(
          "error",
          `Not graded: ${err.errors.length} problem${err.errors.length > 1 ? "s" : ""} (listed ${mine.length ? "under the assignment" : "above"}).`,
        );
        if (mine.length) this.errors.scrollIntoView({ block: "nearest" });
      } else if (tokenProblem(err)) {
        this.needToken(err);
      } else {
        this.setStatus("error", `Could not start grading: ${err.message}.`);
      }
      return;
    }
    this.showErrors([]);
    this.showSubErrors([]);
    this.results.hidden = true; // the last run's table goes until this one is done
    this.closeDetail(false);
    await this.follow(state.id, { state });
  }

  /** Follow a run until it ends (polling every POLL_MS); `quiet`: a run from an earlier visit, forgotten if gone. */
  async follow(id, { state = null, quiet = false } = {}) {
    const token = ++this.token;
    store.set("grading.run", id);
    this.gradeButton.disabled = true;
    let misses = 0;
    try {
      while (token === this.token) {
        if (!state) {
          try {
            state = await grade.state(id);
            misses = 0;
          } catch (err) {
            if (err instanceof ApiError && err.status === 404) {
              store.set("grading.run", null);
              if (!quiet) this.setStatus("error", "The grading run is gone (the server's data was removed?).");
              return;
            }
            if (tokenProblem(err)) {
              this.needToken(err, quiet);
              return;
            }
            if (++misses > 20) {
              this.setStatus("error", `Lost the grading run: ${err.message}.`);
              return;
            }
            await sleep(POLL_MS * 2);
            continue;
          }
        }
        if (token !== this.token) return;
        this.showProgress(state);
        if (state.status === "done") {
          this.showResults(state);
          return;
        }
        if (state.status === "failed") {
          this.setStatus("error", `Grading failed: ${state.error || "no reason given"}.`);
          return;
        }
        state = null;
        await sleep(POLL_MS);
      }
    } finally {
      if (token === this.token) this.gradeButton.disabled = false;
    }
  }

  /** A link to a file of the run: a click fetches it with the instructor's token, then opens it in a new
   * tab, or saves it as `save`. */
  fileLink(url, attrs, text, save = null) {
    const a = h("a", { ...attrs, href: url }, text);
    a.addEventListener("click", (e) => {
      e.preventDefault();
      const name = url.split("/").pop();
      (save ? downloadFile(url, save, AS) : openFile(url, AS)).catch((err) =>
        this.setStatus("error", `Could not open ${name}: ${err.message}.`),
      );
    });
    return a;
  }

  /** A request was refused for want of the instructor's token: say so, and point at the field. */
  needToken(err, quiet = false) {
    this.setStatus("error", tokenProblem(err));
    this.tokenInput.setAttribute("aria-invalid", "true");
    if (!quiet) this.tokenInput.focus();
  }

  setStatus(kind, text) {
    this.status.dataset.kind = kind;
    this.status.textContent = text;
  }

  showProgress(st) {
    const total = st.renders_total;
    const done = st.renders_done || 0;
    this.root.dataset.status = st.status;
    this.progress.hidden = st.status !== "running";
    this.progress.max = total || 1;
    this.progress.value = total ? done : 0;
    const n = (st.students || []).length;
    if (st.status === "running") {
      const renders = total === null || total === undefined ? "preparing the renders" : `renders ${done}/${total}`;
      this.setStatus("busy", `Grading ${n} student${n === 1 ? "" : "s"}: ${renders}`);
    } else if (st.status === "done") {
      this.setStatus("ok", `Graded ${n} student${n === 1 ? "" : "s"} (${total ?? 0} render${total === 1 ? "" : "s"}).`);
    }
  }

  // -- the results --------------------------------------------------------------------------------

  showResults(st) {
    this.run = st;
    this.reports = new Map(st.reports.map((r) => [r.student, r]));
    const stats = st.summary?.statistics || {};
    const tests = [];
    for (const r of st.reports) {
      for (const t of r.tests)
        if (!tests.some((x) => x.name === t.name)) tests.push({ name: t.name, kind: t.kind, max: t.max_score });
    }
    tests.sort((a, b) => (TEST_ORDER[a.kind] ?? 9) - (TEST_ORDER[b.kind] ?? 9)); // stable: the assignment's order within a kind
    this.tests = tests;
    const byStatus = stats.by_status || {};
    const stat = (label, value, key) => h("div", { dataset: { stat: key } }, h("dt", {}, label), h("dd", {}, value));
    this.tableBox = h("div", {
      class: "grade-table-box",
      role: "region",
      "aria-labelledby": "grade-caption",
      tabindex: 0,
    });
    this.results.replaceChildren(
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-grade-results" }, "Results"),
        h("span", { class: "muted" }, st.assignment || ""),
        h(
          "span",
          { class: "toolbar" },
          this.fileLink(
            grade.summaryUrl(st.id, "csv"),
            { class: "button", id: "grade-csv", download: "summary.csv" },
            "summary.csv",
            "summary.csv",
          ),
          this.fileLink(grade.summaryUrl(st.id, "json"), { class: "button", id: "grade-json" }, "summary.json"),
        ),
      ),
      h(
        "dl",
        { class: "stats grade-stats", id: "grade-stats", "aria-label": "Class statistics" },
        stat("students", stats.students ?? st.reports.length, "students"),
        stat("mean", percentText(stats.mean_percent), "mean"),
        stat("min", percentText(stats.min_percent), "min"),
        stat("max", percentText(stats.max_percent), "max"),
        stats.max_scores
          ? stat(
              "out of",
              Object.entries(stats.max_scores)
                .map(([kind, n]) => `${pts(n)} (${kind})`)
                .join(" · "),
              "out-of",
            )
          : null,
        ...["graded", "invalid", "failed"].map((s) => stat(s, byStatus[s] ?? 0, s)),
      ),
      h(
        "p",
        { class: "hint" },
        "Click a student (or focus the row and press Enter) for their pictures and every test's output. A test's output is also its cell's tooltip.",
      ),
      this.tableBox,
    );
    this.results.hidden = false;
    this.renderTable();
    const open = this.detail.hidden ? null : this.detail.dataset.student;
    if (open && this.reports.has(open)) this.showDetail(open, false);
    else this.closeDetail(false);
  }

  columns() {
    const cols = [
      { key: "student", label: "Student", sort: (r) => r.student.toLowerCase(), first: 1 },
      { key: "kind", label: "Kind", sort: (r) => r.kind, first: 1 },
      { key: "status", label: "Status", sort: (r) => r.status, first: 1 },
      { key: "score", label: "Score", sort: (r) => (share(r) ?? 0) + r.score * 1e-6, first: -1 },
    ];
    for (const [key, label, , first] of METRICS)
      cols.push({ key, label, sort: (r) => r.metrics?.[key] ?? null, first, metric: true });
    return cols;
  }

  sortedReports() {
    const col = this.columns().find((c) => c.key === this.sort.key) || this.columns()[0];
    return this.sort.sorted(this.run.reports, col.sort, (a, b) => a.student.localeCompare(b.student));
  }

  renderTable() {
    const cols = this.columns();
    const sortable = (c) =>
      this.sort.header(c.key, c.label, {
        first: c.first,
        num: c.metric,
        redraw: () => this.renderTable(),
        within: this.tableBox,
      });
    const [student, kind, status, score, ...metrics] = cols;
    const head = h(
      "tr",
      {},
      sortable(student),
      sortable(kind),
      sortable(status),
      sortable(score),
      ...this.tests.map((t) =>
        h(
          "th",
          {
            scope: "col",
            class: "test",
            dataset: { test: t.name },
            title: `${t.name} (${t.kind}, ${pts(t.max)} points)`,
          },
          t.name,
          h("small", {}, ` /${pts(t.max)}`),
        ),
      ),
      ...metrics.map(sortable),
    );
    const rows = this.sortedReports().map((r) => {
      const byName = new Map(r.tests.map((t) => [t.name, t]));
      const row = h(
        "tr",
        {
          tabindex: 0,
          class: "student",
          dataset: { student: r.student, status: r.status },
          "aria-label": `${r.student}: ${pts(r.score)} of ${pts(r.max_score)} (${percentText(share(r))}), ${r.status}; Enter shows the details`,
        },
        h("th", { scope: "row" }, r.student),
        h("td", {}, r.kind),
        h("td", {}, h("span", { class: `badge ${r.status}` }, r.status)),
        h(
          "td",
          { class: "num score" },
          h("strong", {}, pts(r.score)),
          ` / ${pts(r.max_score)} `,
          h("span", { class: "pct" }, `(${percentText(share(r))})`),
        ),
        ...this.tests.map((c) => {
          const t = byName.get(c.name);
          if (!t)
            return h(
              "td",
              { class: "test na", title: "not a test for this kind of submission" },
              h("span", { "aria-hidden": "true" }, "·"),
              h("span", { class: "sr-only" }, "not tested"),
            );
          const ok = t.status === "passed";
          return h(
            "td",
            { class: `test ${ok ? "pass" : "fail"}`, title: t.output, dataset: { test: t.name, status: t.status } },
            h("span", { class: "pf", "aria-hidden": "true" }, ok ? "✓" : "✗"),
            h("span", { class: "sr-only" }, ok ? "passed, " : "failed, "),
            pts(t.score),
          );
        }),
        ...METRICS.map(([key, , fmt]) => h("td", { class: "num", dataset: { metric: key } }, fmt(r.metrics?.[key]))),
      );
      row.addEventListener("click", () => this.showDetail(r.student));
      row.addEventListener("keydown", (e) => {
        if (e.target !== row) return;
        if (e.key === "Enter" || e.key === " ") {
          e.preventDefault();
          this.showDetail(r.student);
        } else if (e.key === "ArrowDown" || e.key === "ArrowUp") {
          e.preventDefault();
          (e.key === "ArrowDown" ? row.nextElementSibling : row.previousElementSibling)?.focus();
        }
      });
      if (!this.detail.hidden && this.detail.dataset.student === r.student) row.setAttribute("aria-current", "true");
      return row;
    });
    const table = h(
      "table",
      { class: "grade-table", id: "grade-table" },
      h(
        "caption",
        { id: "grade-caption" },
        `The class: ${this.run.reports.length} students, by ${this.sort.key}${this.sort.dir > 0 ? "" : " (descending)"}`,
      ),
      h("thead", {}, head),
      h("tbody", {}, rows),
    );
    this.tableBox.replaceChildren(table);
  }

  closeDetail(focusRow = true) {
    const student = this.detail.dataset.student;
    this.detail.hidden = true;
    delete this.detail.dataset.student;
    for (const tr of this.tableBox?.querySelectorAll("tr[aria-current]") || []) tr.removeAttribute("aria-current");
    if (focusRow && student) this.tableBox.querySelector(`tr[data-student="${CSS.escape(student)}"]`)?.focus();
  }

  showDetail(student, focus = true) {
    const r = this.reports.get(student);
    if (!r) return;
    const id = this.run.id;
    for (const tr of this.tableBox.querySelectorAll("tbody tr")) {
      if (tr.dataset.student === student) tr.setAttribute("aria-current", "true");
      else tr.removeAttribute("aria-current");
    }
    const m = r.metrics || {};
    const base = m.baseline || {};
    const captions = {
      render: r.kind === "image" ? "their image" : `their scene, rendered${m.spp ? ` (${m.spp} spp)` : ""}`,
      reference: "the reference",
      error_map: `FLIP error map${typeof m.flip === "number" ? ` (mean ${fixed(m.flip, 3)})` : ""}`,
      rejected:
        m.captions?.rejected ||
        `pixels the z test rejected${typeof m.rejected === "number" ? ` (${fixed(100 * m.rejected, 2)} %)` : ""}`, // the grader's words: red beyond noise, yellow as noise
    };
    const images = new Set(r.images || []);
    const figures = PICTURES.map(([name, alt]) =>
      h(
        "figure",
        { class: "grade-fig", dataset: { picture: name } },
        images.has(name)
          ? this.fileLink(
              grade.fileUrl(id, student, `${name}.png`),
              { title: "open the PNG" },
              picture(grade.fileUrl(id, student, `${name}.png`), `${alt} of ${student}`),
            )
          : h("div", { class: "grade-noimg" }, "no picture"),
        h("figcaption", {}, captions[name]),
      ),
    );
    const metricRows = METRICS.filter(([key]) => m[key] !== undefined && m[key] !== null).map(([key, label, fmt]) =>
      h(
        "tr",
        {},
        h("th", { scope: "row" }, label),
        h("td", { class: "num" }, fmt(m[key])),
        h("td", { class: "num" }, fmt(base[key])),
      ),
    );
    const tests = r.tests.map((t) => {
      const ok = t.status === "passed";
      const multi = t.output.includes("\n");
      return h(
        "li",
        { class: `grade-test ${ok ? "pass" : "fail"}`, dataset: { test: t.name, status: t.status } },
        h(
          "div",
          { class: "grade-test-head" },
          h("span", { class: "pf", "aria-hidden": "true" }, ok ? "✓" : "✗"),
          h("strong", {}, t.name),
          h("span", { class: "muted" }, t.kind),
          h("span", { class: `badge ${ok ? "passed" : "failed"}` }, ok ? "passed" : "failed"),
          h("span", { class: "pts" }, `${pts(t.score)} / ${pts(t.max_score)}`),
        ),
        multi ? h("pre", { class: "grade-output" }, t.output) : h("p", { class: "grade-output" }, t.output),
      );
    });
    const problem = (e) =>
      h("li", {}, e.path ? h("code", {}, e.path) : h("code", {}, "(the submission)"), " ", e.message);
    const parts = [
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-grade-detail", tabindex: -1 }, student),
        h(
          "span",
          {},
          h("strong", {}, `${pts(r.score)} / ${pts(r.max_score)}`),
          ` (${percentText(share(r))}) · `,
          r.kind,
          " · ",
          h("span", { class: `badge ${r.status}` }, r.status),
        ),
        h(
          "span",
          { class: "toolbar" },
          this.fileLink(
            grade.fileUrl(id, student, "results.json"),
            { class: "button", title: "Gradescope's autograder results" },
            "results.json",
          ),
          this.fileLink(grade.fileUrl(id, student, "report.json"), { class: "button" }, "report.json"),
          h("button", { type: "button", id: "grade-detail-close", onclick: () => this.closeDetail() }, "Close"),
        ),
      ),
      r.errors?.length
        ? h(
            "div",
            { class: "message grade-problems", dataset: { kind: "error" } },
            h(
              "strong",
              {},
              r.kind === "image"
                ? "The image could not be graded:"
                : `The scene is invalid (${r.errors.length} error${r.errors.length > 1 ? "s" : ""}):`,
            ),
            h("ul", { id: "grade-detail-errors" }, r.errors.map(problem)),
          )
        : null,
      r.warnings?.length
        ? h(
            "div",
            { class: "message grade-problems", dataset: { kind: "warn" } },
            h("strong", {}, "Warnings:"),
            h("ul", {}, r.warnings.map(problem)),
          )
        : null,
      images.size
        ? h("div", { class: "grade-figs" }, figures)
        : h("p", { class: "hint" }, "No pictures: the submission was not rendered or compared (see the errors)."),
      metricRows.length
        ? h(
            "div",
            { class: "grade-metrics-box" },
            h("h3", { id: "grade-metrics-h" }, "Against the reference"),
            h(
              "p",
              { class: "hint" },
              "The noise baseline is the reference scene rendered again with the student's samples and another seed: the difference that noise alone makes.",
            ),
            h(
              "table",
              { class: "grade-metrics", "aria-labelledby": "grade-metrics-h" },
              h(
                "thead",
                {},
                h(
                  "tr",
                  {},
                  h("th", { scope: "col" }, "metric"),
                  h("th", { scope: "col", class: "num" }, student),
                  h("th", { scope: "col", class: "num" }, "noise baseline"),
                ),
              ),
              h("tbody", {}, metricRows),
            ),
          )
        : null,
      h("h3", {}, "Tests"),
      h("ol", { class: "grade-tests", id: "grade-detail-tests" }, tests),
    ];
    this.detail.replaceChildren(...parts.filter(Boolean));
    this.detail.dataset.student = student;
    this.detail.hidden = false;
    if (focus) {
      this.detail.scrollIntoView({ behavior: "smooth", block: "start" });
      $("#h-grade-detail", this.detail).focus({ preventScroll: true });
    }
  }
}
